"""OMSimulator's dcmotor system as its SSD wires it (configs/dcmotor.yaml): three Dymola FMUs, the
stimuli FMU's voltage and load torque as signals, the inertia's angle fed back to the machine, and
the shaft a physical-port coupling with probed signs. Runs are shortened with T (the file's own
horizon is 1 s). Skipped when ../shared/third_party is absent (a fresh clone)."""
from pathlib import Path

import numpy as np
import pytest

import wavecosim as wc
from wavecosim.cli import main

ROOT = Path(__file__).resolve().parent.parent

DCMOTOR = ROOT.parent / "shared" / "third_party" / "dcmotor"
CONFIG = ROOT / "configs" / "dcmotor.yaml"
pytestmark = pytest.mark.skipif(not DCMOTOR.exists(), reason="the third-party FMUs (../shared/third_party) are absent")

CLASSICAL = ["explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils", "newton"]


def quiet(message):
    """The sign-probe notes are not under test here."""


def test_dr_converges_to_the_monolithic_reference_as_K_grows():
    """Max error over 0.05 s (50 steps of the start-up transient) against the interface Newton,
    whose acceptance is relative to the port waves here (the machine is smooth to about 4e-7)."""
    sc = wc.load(CONFIG, T=0.05)
    errors = {K: wc.simulate(sc, K=K, warn=quiet).summary["max_error"] for K in (0, 10, 20)}
    assert errors[20] < errors[10] < errors[0] and errors[20] <= 1e-6 and errors[0] > 1e-2, errors


def test_the_signals_reach_the_machine_and_the_inertia():
    """U = 12 V and M_load = -0.5 N.m from the stimuli FMU (the SSD's bindings), phi = phiA held
    from the start of each step; the summary says the sources' energy is not a violation."""
    result = wc.simulate(wc.load(CONFIG, T=0.02), K=20, warn=quiet)
    s = result.summary
    assert s["status"] == "finished" and s["signals"] == 3
    assert s["signal_driven_subsystems"] == ["inertia", "machine"] and "legitimate" in s["signal_note"]
    assert np.all(result.trajectory["U"] == 12.0)
    assert s["port_signs"]["machine"]["sign"] == [-1.0] and s["port_signs"]["inertia"]["sign"] == [1.0]
    assert result.trajectory["w"][-1] > 1.0


@pytest.mark.parametrize("master", CLASSICAL)
def test_every_classical_master_runs(master):
    result = wc.simulate(wc.load(CONFIG, T=0.01), master=master, K=5, warn=quiet)
    s = result.summary
    assert s["status"] == "finished" and np.isfinite(s["max_error"]) and s["steps"] == 10
    if master in ("jacobi-iter", "gauss-seidel-iter", "iqn-ils", "newton"):
        assert s["max_error"] <= 1e-4, s["max_error"]


def test_compare_runs_every_master(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["compare", str(CONFIG), "--T", "0.005", "--Ks", "2,20", "--quiet", "--no-certificates",
              "--out", str(tmp_path)])
    assert info.value.code == 0, capsys.readouterr().err
    assert (tmp_path / "compare.json").exists()
