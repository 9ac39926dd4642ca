"""libcosim's ECCO beside `compare --tolerances` (sweeps/ecco.py): on the foreign pair it runs at a
tolerance, its true error is finite and near what the explicit master makes at ECCO's mean step,
its doSteps are its steps times the FMUs, a tighter tolerance makes more steps; the power bond names
the value references libcosim reads from the FMUs; a system without a power bond is one line."""
import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from paths import CLI, CONFIGS
from wavecosim.bench.peers import Refused, installed
from wavecosim.examples import path
from wavecosim.run.fine import fine_reference, true_error
from wavecosim.run.runner import run
from wavecosim.scenario.config import load_scenario
from wavecosim.sweeps.ecco import _request, observed_columns, peer_rows, power_bonds, run_ecco

needs_libcosim = pytest.mark.skipif(not installed("libcosim"), reason="libcosimpy is not installed (the peers extra)")
T = 0.2


@pytest.fixture(scope="module")
def pair():
    """The foreign pair over T and its monolithic reference at T / 4000."""
    scenario = load_scenario(path("foreign_pair")).with_changes("the test", T=T)
    return scenario, fine_reference(scenario, None, dt=T / 4000)


@needs_libcosim
def test_ecco_runs_on_the_foreign_pair_at_a_tolerance(pair):
    scenario, reference = pair
    loose, tight = peer_rows(scenario, [1e-2, 1e-3], reference, ("ecco",))
    for row in (loose, tight):
        assert row["status"] == "finished" and row["mode"] == "ecco"
        assert row["doStep"] == 2 * row["accepted_steps"] and row["rejected_steps"] == 0
    explicit = run(scenario.with_master(algorithm="explicit").with_changes("the test", dt=T / tight["accepted_steps"]),
                   None, certificates=False, warn=lambda message: None)
    assert 0.2 < tight["true_error"] / true_error(explicit, reference)["true_error"] < 5
    assert tight["accepted_steps"] > 2 * loose["accepted_steps"] and tight["true_error"] < loose["true_error"]


@needs_libcosim
def test_ecco_counts_every_step_it_makes(pair):
    scenario, reference = pair
    out = run_ecco(_request(scenario, power_bonds(scenario), 1e-3, observed_columns(scenario, reference)))
    t = np.asarray(out["t"])
    assert out["steps"] == len(t) - 1 and t[0] == 0 and t[-1] >= T - 1e-12
    assert np.all(np.diff(t) > 0) and len(set(np.round(np.diff(t), 12))) > 3     # its steps vary
    assert set(out["values"]) == {"x", "v"}


@needs_libcosim
def test_the_power_bond_names_the_value_references_libcosim_reads(pair):
    scenario, _ = pair
    from libcosimpy.CosimEnums import CosimVariableCausality as causality
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimSlave import CosimLocalSlave
    from wavecosim.core.scene import resolve_fmu
    (bond,) = power_bonds(scenario)
    assert (bond.a, bond.a_out, bond.a_in, bond.b, bond.b_out, bond.b_in) == ("A", "v", "F", "B", "F", "v")
    execution = CosimExecution.from_step_size(step_size=10**6)
    seen = {}
    for sub in scenario.subsystems:
        index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(resolve_fmu(sub)), instance_name=sub.name))
        seen[sub.name] = {v.name.decode(): (v.reference, v.causality) for v in execution.slave_variables(index)}
    out, inp = causality.OUTPUT.value, causality.INPUT.value
    expected = (seen["A"]["v"], seen["A"]["F"], seen["B"]["F"], seen["B"]["v"])
    assert tuple(r for r, _ in expected) == bond.refs
    assert [c for _, c in expected] == [out, inp, out, inp]


@needs_libcosim
def test_a_system_without_a_power_bond_is_one_line():
    scenario = load_scenario(path("two_oscillators"))
    lines = []
    assert peer_rows(scenario, [1e-3], None, ("ecco",), note=lines.append) == []
    assert lines == ["libcosim's ECCO skipped: no power bond: A's port is not a physical port (an effort and a "
                     "flow, in and out)"]


@pytest.mark.parametrize("change, words", [({"input": ["effort"]}, "both take the effort"),
                                           ({"sign": [1.0]}, "opposite signs"),
                                           ({"sign": []}, "opposite signs")])
def test_a_port_pair_libcosim_cannot_connect_unchanged_is_no_power_bond(pair, change, words):
    scenario, _ = pair
    a, b = scenario.subsystems
    changed = scenario.with_changes("the test", subsystems=[a, dataclasses.replace(b, port={**b.port, **change})])
    with pytest.raises(Refused, match=words):
        power_bonds(changed)


def test_libcosimpy_missing_is_one_line_and_no_rows(monkeypatch):
    monkeypatch.setitem(sys.modules, "libcosimpy", None)          # import libcosimpy fails, as where it is absent
    lines = []
    assert peer_rows(load_scenario(path("foreign_pair")), [1e-3], None, ("ecco",), note=lines.append) == []
    assert lines == ["libcosim's ECCO skipped: --peers ecco needs libcosimpy, which is not installed here: "
                     "pip install 'wavecosim[peers]'"]


@pytest.mark.parametrize("args, words", [(["--tolerances", "1e-2", "--peers", "nope"], "unknown peer 'nope'"),
                                         (["--peers", "ecco"], "goes with --tolerances")])
def test_a_wrong_peers_option_is_one_line(tmp_path, args, words):
    done = subprocess.run([*CLI, "compare", str(CONFIGS / "foreign_pair.yaml"), *args, "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and words in done.stderr and len(done.stderr.strip().splitlines()) == 1
