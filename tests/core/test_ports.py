"""wavecosim/core/ports.py on FMUs built like other tools' exports (configs/foreign_pair.yaml: ForeignMass
and ForeignSpring, physical causality only, no H, no wave mode): the wave adapter makes eq. 12 for
them, DR and the monolithic reference agree through it, every classical master runs on their
physical ports, a missing port sign is found by probing, and without H the run reports the port
energy ledger and what it could not certify."""
import copy
import re

import numpy as np
import pytest

from paths import ROOT
from wavecosim.core import ports
from wavecosim.scenario.config import load_scenario, parse_scenario
from wavecosim.errors import ConfigError, NumericalError, RunFailed
from wavecosim.run.runner import run
from wavecosim.core.scene import build_scene

SCENE = ROOT / "configs" / "foreign_pair.yaml"
CLASSICAL = ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils", "newton")


@pytest.fixture(scope="module")
def pair():
    return load_scenario(SCENE).with_changes(T=0.2)


@pytest.fixture(scope="module")
def dr_run(pair):
    return run(pair, reference="lockstep", warn=lambda msg: None)


def signs_of(summary):
    """The summary's port signs without the probe figures."""
    return {k: {"sign": v["sign"], "probed": v["probed"]} for k, v in summary["port_signs"].items()}


def without_signs(scenario, flip=()):
    """A copy with the port signs removed (probed at set-up), or with the named subsystems' flipped."""
    copied = copy.deepcopy(scenario)
    for sub in copied.subsystems:
        if sub.name in flip:
            sub.port["sign"] = [-s for s in sub.port["sign"]]
        elif not flip:
            del sub.port["sign"]
    return copied


def test_dr_through_the_adapter_meets_the_monolithic_reference(dr_run):
    """K = 50 at gamma auto: the error against the monolithic step is at roundoff (measured 3e-14)."""
    s = dr_run.summary
    assert s["status"] == "finished" and s["iterations_mean"] == 50
    assert s["max_error"] <= 1e-9
    assert s["fast_path"] and s["fast_note"] == "C kernel"             # the adapter runs in C


def test_the_error_falls_with_the_inner_budget(pair, dr_run):
    """A budget of 3 leaves a visible error; 50 brings it to roundoff."""
    coarse = run(pair.with_master(K=3), reference="lockstep", warn=lambda msg: None).summary["max_error"]
    assert coarse > 1e3 * dr_run.summary["max_error"]


def test_the_affine_pair_costs_about_one_dostep_per_map_evaluation(dr_run):
    """One doStep per query plus the slope estimate (m + 1 = 2 doSteps) per macro-step: 53 / 51."""
    for name, info in dr_run.summary["wave_adapter"].items():
        assert info["doSteps_per_evaluation"] <= 1.3, name
        assert info["map_evaluations"] >= 51 * 200


@pytest.mark.parametrize("algorithm", CLASSICAL)
def test_every_classical_master_runs_on_physical_ports(pair, algorithm):
    """Iterative masters reach the monolithic step; the explicit ones stay finite and visibly off it."""
    result = run(pair.with_master(algorithm=algorithm, K=20), reference="lockstep", warn=lambda msg: None)
    assert result.status == "finished"
    error = result.summary["max_error"]
    if algorithm in ("explicit", "gauss-seidel"):
        assert 1e-6 < error < 1e-1
    else:
        assert error <= 1e-9


def test_missing_signs_are_found_by_probing(pair, dr_run):
    """Without signs, the probe finds +1 for the mass (dv/dF > 0) and -1 for the spring (dF/dv < 0),
    warns once per channel, and the run is the one with the signs given, to the last bit."""
    notes = []
    probed = run(without_signs(pair), reference="lockstep", warn=notes.append)
    assert signs_of(probed.summary) == {"A": {"sign": [1.0], "probed": True}, "B": {"sign": [-1.0], "probed": True}}
    assert len(notes) == 2 and "dv/dF = 0.001" in notes[0] and "dF/dv = -0.6" in notes[1]
    for sub in probed.summary["port_signs"].values():
        (probe,) = sub["probe"]           # exact FMUs: the first step, confirmed by the next one
        assert probe["steps_tried"] == 2 and probe["check_step"] == pytest.approx(10 * probe["step"], rel=1e-9)
        assert probe["step"] == ports.PROBE_REL and abs(probe["check_slope"] - probe["slope"]) <= 1e-9 * abs(probe["slope"])
    assert probed.trajectory.tobytes() == dr_run.trajectory.tobytes()


@pytest.mark.parametrize("flipped", ["A", "B"])
def test_a_flipped_sign_makes_an_active_port_that_the_probe_corrects(pair, flipped):
    """With one sign flipped the port's incremental impedance is negative and gamma auto refuses;
    removing the sign lets the probe choose the passive orientation again."""
    with pytest.raises(ConfigError, match=f"subsystem {flipped} has no positive incremental port impedance"):
        run(without_signs(pair, flip=[flipped]), warn=lambda msg: None)
    scene = build_scene(without_signs(pair))
    try:
        assert scene.port_signs[flipped]["sign"] == pair.subsystems["AB".index(flipped)].port["sign"]
    finally:
        scene.close()


def test_signs_are_probed_for_physical_masters_too(pair):
    scenario = without_signs(pair).with_master(algorithm="gauss-seidel-iter", K=20)
    result = run(scenario, reference="lockstep", warn=lambda msg: None)
    assert signs_of(result.summary)["B"] == {"sign": [-1.0], "probed": True}
    assert result.summary["max_error"] <= 1e-9


def test_without_h_the_run_keeps_the_port_ledger(dr_run):
    """No r_ or H_total columns; the ledger's per-step entries add up to its cumulated column, the
    mass's kinetic energy never rises by more than the energy its port took in (Condition 2
    checked from outside), and the summary names what could not be certified."""
    steps, s = dr_run.steps, dr_run.summary
    assert not [c for c in steps.dtype.names if c.startswith("r_") or c == "H_total"]
    np.testing.assert_allclose(np.cumsum(steps["port_energy_A"]), steps["port_energy_cum_A"], rtol=1e-12, atol=1e-18)
    kinetic = 0.5 * dr_run.trajectory["v"] ** 2                   # m = 1
    assert np.all(np.diff(kinetic) - steps["port_energy_A"] <= 1e-15)
    assert abs(s["port_energy_by_subsystem"]["A"] + s["port_energy_by_subsystem"]["B"]) < 1e-12
    assert {"r_A", "r_B", "H_total"} <= set(s["certificates_unavailable"])
    assert "H_initial" not in s and dr_run.energy is None


def test_the_ledger_guard_runs_without_h_and_the_monolithic_guard_is_skipped(pair, dr_run):
    """The interface ledger needs no H (it stays at roundoff here); the monolithic guard needs H, so
    it is left out with a note instead of guarding against a made-up energy."""
    assert "ledger" in dr_run.steps.dtype.names and max(dr_run.steps["ledger"]) <= 1e-12
    assert not any(c.startswith("energy_guard") for c in dr_run.summary["certificates_unavailable"])
    monolithic = run(pair.with_master(energy_guard="monolithic"), warn=lambda msg: None).summary
    note = "energy_guard (monolithic: needs every subsystem's stored energy H)"
    assert note in monolithic["certificates_unavailable"]
    assert "energy_guard_steps" not in monolithic


def test_an_unsolved_query_names_the_subsystem_step_and_residual(pair, monkeypatch):
    """Tolerances no roundoff meets: the first query fails, naming its subsystem, step and residual."""
    monkeypatch.setattr(ports, "TOL", 0.0)
    monkeypatch.setattr(ports, "ACCEPT", 0.0)
    with pytest.raises(RunFailed) as failed:
        run(pair.with_changes(gamma=1.0), warn=lambda msg: None)
    assert isinstance(failed.value.error, NumericalError)
    assert re.fullmatch(r"subsystem [AB]: wave adapter at step 0 \(t = 0\): no convergence in 30 Newton iterations "
                        r"\(best relative residual \S+ > 0\); residual \|e \+ gamma f - c a\| = \S+",
                        str(failed.value.error))


def physical_port_scenario(port):
    raw = {"dt": 0.001, "T": 0.01, "gamma": 1.0, "couplings": [{"type": "equal_effort_opposite_flow",
                                                                  "ports": ["A", "B"]}],
           "subsystems": {"A": {"fmu": "ForeignMass", "port": port},
                          "B": {"fmu": "ForeignSpring", "port": {"physical_in": "v", "physical_out": "F",
                                                                  "input": "flow"}}}}
    return parse_scenario(raw, "run.yaml")


MASS_PORT = {"physical_in": "F", "physical_out": "v", "input": "effort"}


@pytest.mark.parametrize("port, message", [
    ({"physical_out": "v", "input": "effort"}, "subsystems.A.port.physical_in: missing required key"),
    ({**MASS_PORT, "sign": 2}, "subsystems.A.port.sign: must be 1 or -1"),
    ({**MASS_PORT, "effort": "v"}, "subsystems.A.port.effort: must be ['F']"),
    ({**MASS_PORT, "physical_in": ["F", "v"]}, "physical_out: has 1 entries but physical_in"),
    ({"wave_in": "a", "sign": 1}, "subsystems.A.port.sign: only a physical port"),
])
def test_physical_port_keys_are_checked(port, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        physical_port_scenario(port)


def test_an_fmu_without_wave_mode_needs_its_physical_port_declared():
    scenario = physical_port_scenario(MASS_PORT)
    scenario.subsystems[0].port = {"wave_in": ["a"], "wave_out": ["b"], "effort": ["e"], "flow": ["f"], "energy": "H"}
    with pytest.raises(ConfigError, match="declare its physical port"):
        build_scene(scenario)


DCMOTOR = ROOT.parent / "shared" / "third_party" / "dcmotor" / "resources"


@pytest.mark.skipif(not DCMOTOR.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_a_real_third_party_pair_through_the_adapter():
    """OMSimulator's dcmotor FMUs (Dymola exports): the machine drives the inertia through the shaft.
    The probe finds the machine power-out (dM/dw < 0) and the inertia power-in (FACTS.md); the
    machine's step map is smooth only to about 4e-7, so some queries stall and keep their best
    point, and DR meets the monolithic step to that level (measured 9.7e-8 over 0.2 s)."""
    raw = {"dt": 0.001, "T": 0.1, "gamma": "auto",
           "subsystems": {"machine": {"fmu": "emachine_model.fmu", "start": {"U": 10.0},
                                      "port": {"physical_in": "w", "physical_out": "M", "input": "flow"}},
                          "inertia": {"fmu": "edrive_mass.fmu",
                                      "port": {"physical_in": "M_A", "physical_out": "wA", "input": "effort"}}},
           "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["machine", "inertia"]}],
           "outputs": {"w": "inertia.wA", "M": "machine.M"}, "error": ["w", "M"]}
    result = run(parse_scenario(raw, "dcmotor.yaml", DCMOTOR), reference="lockstep", warn=lambda msg: None)
    s = result.summary
    assert signs_of(s) == {"machine": {"sign": [-1.0], "probed": True}, "inertia": {"sign": [1.0], "probed": True}}
    assert s["status"] == "finished" and s["max_error"] <= 1e-6
    assert s["wave_adapter"]["machine"]["worst_stalled_residual"] <= ports.ACCEPT
    ledger = s["port_energy_by_subsystem"]
    assert ledger["inertia"] > 0.0 and abs(ledger["machine"] + ledger["inertia"]) <= 1e-6 * ledger["inertia"]
    assert result.column("w")[-1] > 1.0


DUAL_MASS = ROOT.parent / "shared" / "third_party" / "dual_mass_oscillator"


@pytest.mark.skipif(not DUAL_MASS.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_an_fmu_that_cannot_restore_needs_its_sign_given():
    """OMSimulator's dual mass oscillator cannot get and set its state: no orientation probe, so the
    non-iterative masters that could run it ask for the sign."""
    raw = {"dt": 0.001, "T": 0.01, "gamma": 1.0, "master": {"algorithm": "explicit"},
           "subsystems": {"A": {"fmu": "DualMassOscillator.System1.fmu",
                                "port": {"physical_in": "F", "physical_out": "v1", "input": "effort"}},
                          "B": {"fmu": "DualMassOscillator.System2.fmu",
                                "port": {"physical_in": "v1", "physical_out": "F", "input": "flow"}}},
           "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}]}
    with pytest.raises(ConfigError, match="subsystems.A.port.sign: missing, and DualMassOscillator.System1.fmu "
                                          "cannot restore its state for the orientation probe; give the sign"):
        build_scene(parse_scenario(raw, "dual.yaml", DUAL_MASS), wave=False, needs_rollback=False)


def test_the_gamma_probe_is_confirmed_at_once_on_exact_fmus(dr_run):
    """gamma: auto checks each frozen map's probe against a ten times larger step: exact FMUs agree at
    once (to roundoff), so gamma is chosen from the first probe, as without the check."""
    for name, probe in dr_run.summary["gamma_probe"].items():
        assert probe["agreed"] and probe["steps_tried"] == 2 and probe["jacobian_difference"] <= 1e-6, (name, probe)
        assert probe["check_step"] == pytest.approx(10 * probe["step"], rel=1e-12)
