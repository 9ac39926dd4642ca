"""OMSimulator's dcmotor system as its SSD wires it (configs/dcmotor.yaml): three Dymola FMUs, the
stimuli FMU's voltage and load torque as signals, the inertia's angle fed back to the machine, and
the shaft a physical-port coupling with probed signs. Runs are shortened with T (the file's own
horizon is 1 s). Skipped when ../shared/third_party is absent (a fresh clone)."""

import numpy as np
import pytest

from paths import ROOT
import wavecosim as wc
from wavecosim.cli import main
from wavecosim.scenario.config import load_raw, parse_scenario
from wavecosim.scenario.overrides import apply_overrides


DCMOTOR = ROOT.parent / "shared" / "third_party" / "dcmotor"
CONFIG = ROOT / "configs" / "dcmotor.yaml"
pytestmark = pytest.mark.skipif(not DCMOTOR.exists(), reason="the third-party FMUs (../shared/third_party) are absent")

CLASSICAL = ["explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils", "newton"]


def quiet(message):
    """The sign-probe notes are not under test here."""


def test_dr_converges_to_the_monolithic_reference_as_K_grows():
    """Max error over the first 20 steps of the start-up transient against the interface Newton,
    whose acceptance is relative to the port waves here (the machine is smooth to about 4e-7)."""
    table = wc.sweep(wc.load(CONFIG, T=0.02), Ks=[0, 10, 20], certificates=False)
    errors = {row["K"]: row["max_error"] for row in table.rows}
    assert errors[20] < errors[10] < errors[0] and errors[20] <= 1e-6 and errors[0] > 1e-2, errors


def test_the_signals_reach_the_machine_and_the_inertia():
    """U = 12 V and M_load = -0.5 N.m from the stimuli FMU (the SSD's bindings), phi = phiA held
    from the start of each step; the summary says the sources' energy is not a violation."""
    result = wc.simulate(wc.load(CONFIG, T=0.02), K=20, reference=False, warn=quiet)
    s = result.summary
    assert s["status"] == "finished" and s["signals"] == 3
    assert s["signal_driven_subsystems"] == ["inertia", "machine"] and "legitimate" in s["signal_note"]
    assert np.all(result.trajectory["U"] == 12.0)
    assert s["port_signs"]["machine"]["sign"] == [-1.0] and s["port_signs"]["inertia"]["sign"] == [1.0]
    assert result.trajectory["w"][-1] > 1.0


@pytest.mark.slow
def test_every_classical_master_runs():
    """Each on physical ports (newton on waves through the adapter); the iterating ones meet newton."""
    sc = wc.load(CONFIG, T=0.01)
    runs = {m: wc.simulate(sc, master=m, K=5, reference=False, warn=quiet) for m in CLASSICAL}
    reference = runs["newton"].trajectory
    for master, result in runs.items():
        traj = result.trajectory
        error = np.hypot(traj["w"] - reference["w"], traj["M"] - reference["M"]).max()
        assert result.summary["status"] == "finished" and result.summary["steps"] == 10 and np.isfinite(error)
        if master in ("jacobi-iter", "gauss-seidel-iter", "iqn-ils"):
            assert error <= 1e-4, (master, error)


@pytest.mark.slow  # a long compare: every master and budget
def test_compare_runs_every_master(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["compare", str(CONFIG), "--T", "0.005", "--Ks", "5", "--quiet", "--no-certificates",
              "--out", str(tmp_path)])
    assert info.value.code == 0, capsys.readouterr().err
    assert (tmp_path / "compare.json").exists()


def test_a_noisy_machine_is_probed_past_its_noise_floor():
    """At R = 1.0 and J = 0.004 the machine's one-step map jumps by about 1.1e-5 N.m between nearby
    speeds (its own solver), so the orientation probe's first step of 1e-4 reads dM/dw = +0.107; the
    probe grows the step until two agree (-0.0062 at 0.1, -0.0063 at 1) and keeps the machine
    power-out. gamma: auto then finds a positive bound (about 6.3e-3) and DR meets the reference."""
    sets = [("subsystems.machine.parameters.resistor.R", 1.0), ("subsystems.inertia.parameters.inertia.J", 0.004)]
    scenario = parse_scenario(apply_overrides(load_raw(CONFIG), sets), str(CONFIG), CONFIG.parent)
    result = wc.simulate(scenario.with_changes(T=0.02), warn=quiet)
    s = result.summary
    machine, inertia = s["port_signs"]["machine"], s["port_signs"]["inertia"]
    assert machine["sign"] == [-1.0] and inertia["sign"] == [1.0]
    (probe,) = machine["probe"]
    assert probe["steps_tried"] > 2 and probe["step"] >= 1e-2 and probe["slope"] < 0 and probe["check_slope"] < 0
    assert inertia["probe"][0]["steps_tried"] == 2
    assert s["gamma_mode"] == "auto" and 5e-3 < s["gamma_fne_bounds"]["machine"] < 8e-3
    assert s["gamma_initial"]["machine"] <= 0.9 * (1 + 1e-12) * s["gamma_fne_bounds"]["machine"]
    assert all(p["agreed"] for p in s["gamma_probe"].values())
    assert s["status"] == "finished" and s["max_error"] <= 1e-5 and s["fne_watch_ok"]
