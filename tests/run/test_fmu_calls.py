"""summary.json's fmu_calls: every FMU of the scene counted (those stepped alone, signals only, too),
once, where the calls are made, the same on the C kernel route and the Python one; and equal to
what an FMU counts itself (StrictMass's nDoStep, nGetFMUstate, nSetFMUstate, nGet and nSet outputs,
which no restore undoes)."""
import copy

import pytest
import yaml

import wavecosim as wc
from wavecosim.errors import ConfigError
from paths import CONFIGS, THIRD_PARTY
from wavecosim.masters import MASTERS
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

T = 0.05
CALLS = ("doStep", "save", "restore", "get", "set")
OWN = {"doStep": "nDoStep", "save": "nGetFMUstate", "restore": "nSetFMUstate", "get": "nGet", "set": "nSet"}
# Two StrictMasses coupled by signals only (each one's velocity pushes the other): no port, every
# FMU stepped alone.
SIGNAL_PAIR = {"name": "signal_pair", "dt": 0.001, "T": T,
               "subsystems": {"A": {"fmu": "StrictMass", "start": {"v": 0.5}}, "B": {"fmu": "StrictMass"}},
               "signals": [{"from": "A.v", "to": "B.F", "factor": -2.0}, {"from": "B.v", "to": "A.F"}],
               "outputs": {"vA": "A.v", "vB": "B.v", **{f"{k}{s}": f"{s}.{v}" for k, v in OWN.items() for s in "AB"}}}
PAIR = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
PAIR["subsystems"]["A"]["fmu"] = "StrictMass"
PAIR.update(T=T, fne_watch=False)
PAIR["outputs"].update({f"{k}A": f"A.{v}" for k, v in OWN.items()})


def simulate(scenario, fast):
    return wc.simulate(scenario.with_master("options", fast=fast), reference=False, certificates=False,
                       warn=lambda message: None)


@pytest.mark.parametrize("scene,fmus", [
    (CONFIGS / "two_oscillators.ssd", 2), (CONFIGS / "two_oscillators.yaml", 2), ("signal pair", 2),
    ("StrictMass.fmu", 1), (THIRD_PARTY / "omsimulator" / "LinearTransformation", 2),
    (THIRD_PARTY / "omsimulator" / "LinearTransformation3", 2),
    (THIRD_PARTY / "reference_fmus" / "fmi2" / "VanDerPol.fmu", 1), (CONFIGS / "dcmotor.yaml", 3)])
def test_an_explicit_run_makes_one_doStep_per_fmu_and_step_on_both_routes(scene, fmus, built_fmus):
    """fmu_calls.doStep = steps x FMUs, with and without the C kernel, signal-only scenes, a single
    FMU and an SSD included; fmu_calls_by_subsystem adds up to it."""
    if scene == "signal pair":
        scenario = parse_scenario(copy.deepcopy(SIGNAL_PAIR), "pair.yaml")
    else:
        path = built_fmus["StrictMass"] if scene == "StrictMass.fmu" else scene
        if not THIRD_PARTY.is_dir() and (THIRD_PARTY in path.parents or path.name == "dcmotor.yaml"):
            pytest.skip("the third-party FMUs are not here")
        scenario = wc.load(path, T=T, warn=lambda message: None)
    scenario = scenario.with_master("options", algorithm="explicit")
    fast, python = simulate(scenario, True), simulate(scenario, False)
    steps = fast.summary["steps"]
    assert steps == scenario.n_steps and fast.status == "finished"
    assert fast.summary["fmu_calls"] == python.summary["fmu_calls"]
    assert steps_only(fast.summary["fmu_calls"]) == {"doStep": steps * fmus, "save": 0, "restore": 0}
    by = fast.summary["fmu_calls_by_subsystem"]
    assert len(by) == fmus and all(steps_only(c) == {"doStep": steps, "save": 0, "restore": 0} for c in by.values())
    assert all(c["get"] >= steps for c in by.values())        # at least the outputs recorded after each step
    assert by == python.summary["fmu_calls_by_subsystem"]


def steps_only(calls):
    """The doStep, save and restore counts of fmu_calls."""
    return {k: calls[k] for k in CALLS[:3]}


def own_counts(result, subsystem):
    """What the FMU counted itself over the run: its counters at the last row less at the first."""
    return {k: int(result.column(f"{k}{subsystem}")[-1] - result.column(f"{k}{subsystem}")[0]) for k in CALLS}


@pytest.mark.parametrize("fast", [True, False])
def test_a_signal_only_scene_counts_what_its_fmus_count(fast):
    result = run(parse_scenario(copy.deepcopy(SIGNAL_PAIR), "pair.yaml").with_master("options", fast=fast), None,
                 warn=lambda message: None)
    by = result.summary["fmu_calls_by_subsystem"]
    assert by == {s: own_counts(result, s) for s in "AB"} and by["A"]["doStep"] == result.summary["steps"]
    assert result.summary["fmu_calls"] == {k: by["A"][k] + by["B"][k] for k in CALLS}


def test_a_signal_only_scene_keeps_the_strict_fmus_order_under_a_tolerance():
    """The same pair in the tolerance mode (each FMU set up with a tolerance, tightened by
    fmu_tolerance): its varying steps, rejected ones put back from saved states, are all in the FMI
    order StrictMass checks, and counted as it counts them."""
    raw = copy.deepcopy(SIGNAL_PAIR)
    for sub in raw["subsystems"].values():
        sub["tolerance"] = 1e-4
    raw["master"] = {"tolerance": 1e-4}
    result = run(parse_scenario(raw, "pair.yaml"), None, certificates=False, warn=lambda message: None)
    s = result.summary
    assert s["status"] == "finished" and s["fmu_tolerance"] == {"A": 1e-3 * 1e-4, "B": 1e-3 * 1e-4}
    assert s["accepted_steps"] > 0 and s["rejected_steps"] > 0
    assert s["fmu_calls_by_subsystem"] == {k: own_counts(result, k) for k in "AB"}


@pytest.mark.parametrize("master", list(MASTERS))
@pytest.mark.parametrize("fast", [True, False])
def test_every_master_counts_what_the_fmu_counts(master, fast):
    """The foreign pair with StrictMass as the mass, every master and route: the mass's doSteps, state
    saves and restores as summary.json gives them are those the FMU took (rollbacks included)."""
    raw = copy.deepcopy(PAIR)
    raw["master"] = {"algorithm": master, "K": 3, "fast": fast}
    result = run(parse_scenario(raw, "pair.yaml"), None, certificates=False, warn=lambda message: None)
    mine = result.summary["fmu_calls_by_subsystem"]["A"]
    assert mine == own_counts(result, "A") and mine["doStep"] >= result.summary["steps"]
    if MASTERS[master].needs_rollback:
        assert mine["save"] == result.summary["steps"] and mine["restore"] > 0


@pytest.mark.parametrize("master", list(MASTERS))
@pytest.mark.parametrize("fast", [True, False])
def test_substeps_and_the_tolerance_mode_keep_the_strict_fmus_order(master, fast):
    """StrictMass (its layer refuses a call out of the FMI state machine, a doStep from another time
    than its own, a state it did not give) as the foreign pair's mass with 3 substeps, then under a
    tolerance (its rejected steps put back from saved states): every call it takes is in order, and
    counted as it counts them; a master that holds its inputs also from rest (its pilot steps) with the
    coupling estimate (each step made again and put back). (Substeps behind the wave adapter are refused
    on the kernel route.)"""
    changes = [{"subsystems": {"A": {"substeps": 3}}, "master": {"algorithm": master, "K": 3, "fast": fast}},
               {"master": {"algorithm": master, "K": 3, "fast": fast, "tolerance": 1e-3}}]
    if master in ("explicit", "gauss-seidel"):
        changes.append({"error": ["v"],              # the mass's speed, zero at t0: the pilot steps first
                        "master": {"algorithm": master, "fast": fast, "tolerance": 1e-3, "estimate": "coupling"}})
    for change in changes:
        raw = copy.deepcopy(PAIR)
        raw["subsystems"]["A"].update(change.get("subsystems", {}).get("A", {}))
        raw["master"] = change["master"]
        raw["error"] = change.get("error", raw["error"])
        scenario = parse_scenario(raw, "pair.yaml")
        if fast and "subsystems" in change and MASTERS[master].wave:
            with pytest.raises(ConfigError, match="substeps per macro-step with a wave adapter"):
                run(scenario, None, certificates=False, warn=lambda message: None)
            continue
        result = run(scenario, None, certificates=False, warn=lambda message: None)
        assert result.summary["status"] == "finished", result.summary.get("message")
        mine = result.summary["fmu_calls_by_subsystem"]["A"]
        assert mine == own_counts(result, "A") and mine["doStep"] >= result.summary["steps"]
        if change["master"].get("estimate") == "coupling":
            assert result.summary["pilot"] is True and result.summary["estimate"] == "coupling"
            assert mine["doStep"] >= 2 * result.summary["steps"]
