"""The peers as oracles: every system of ../shared/third_party (and the in-repo .ssd scenes) that a
peer loads, run by wavecosim's explicit master and by the peer (libcosim, an FMPy loop, Ecos where
it installs), every common Real output column agreeing to max |Δy| / range ≤ 1e-9, or differing by
no more than a documented reason (bench/peers.py: known_deviation) explains. A peer that refuses
a file says why in one line. docs/compatibility.md is generated from the same comparisons."""
import functools

import pytest

from paths import CONFIGS, THIRD_PARTY
from wavecosim.bench.peers import AGREE, Refused, agreement, compare, corpus, installed, load_system, ours, verdict
from wavecosim.errors import ConfigError

pytestmark = pytest.mark.slow
SYSTEMS = corpus(THIRD_PARTY, sorted(CONFIGS.glob("*.ssd"))) if THIRD_PARTY.is_dir() else \
    corpus(CONFIGS / "none", sorted(CONFIGS.glob("*.ssd")))
PEERS = ["libcosim", "fmpy", pytest.param("ecos", marks=pytest.mark.skipif(
    not installed("ecos"), reason="ecospy does not import here (it needs the system's libtbb12)"))]


@functools.lru_cache(maxsize=None)
def scenario_of(path):
    return load_system(path)


@pytest.mark.parametrize("peer", PEERS)
@pytest.mark.parametrize("name, path", SYSTEMS, ids=[n for n, _ in SYSTEMS])
def test_wavecosim_agrees_with_the_peer(name, path, peer):
    try:
        scenario = scenario_of(path)
        errors = compare(scenario, path, peer)
    except ConfigError as exc:                  # a file wavecosim refuses in one line (no co-simulation)
        assert "\n" not in str(exc)
        pytest.skip(f"wavecosim refuses it: {exc}")
    except Refused as exc:
        assert "\n" not in str(exc) and str(exc)
        pytest.skip(str(exc))
    ok, words = verdict(peer, path, scenario, errors)
    assert ok, f"{name}, {peer}: {words}: {errors}"


def test_libcosim_is_installed_for_the_peer_tests():
    assert installed("libcosim"), "the test extra installs libcosimpy: pip install -e '.[test]'"


@pytest.mark.skipif(not (THIRD_PARTY / "reference_fmus").is_dir(), reason="the third-party FMUs are not here")
def test_a_changed_result_is_caught():
    path = THIRD_PARTY / "reference_fmus" / "fmi2" / "VanDerPol.fmu"
    scenario = load_system(path)
    mine = ours(scenario)
    mine["VanDerPol.x0"] = mine["VanDerPol.x0"] * (1 + 1e-8)
    errors = agreement(mine, ours(scenario))
    assert errors["VanDerPol.x1"] == 0 and errors["VanDerPol.x0"] > AGREE
    assert not verdict("libcosim", path, scenario, errors)[0]
