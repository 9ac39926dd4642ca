"""OMSimulator's dcmotor system as its SSD wires it (configs/dcmotor.yaml): three Dymola FMUs, the
stimuli FMU's voltage and load torque as signals, the inertia's angle fed back to the machine, and
the shaft a physical-port coupling with probed signs. Runs are shortened with T (the file's own
horizon is 1 s). Skipped when ../shared/third_party is absent (a fresh clone)."""

import os
import subprocess
import sys

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


# The Dymola FMUs call glibc's exp, log and pow, which take their FMA variants where the CPU has FMA and
# AVX2 (other last bits); the FMUs' variable-step solver turns those bits into other internal steps, so
# the reference's floor at K = 20 is 4.1e-7 with the plain variants and 2.5e-6 with the FMA ones
# (GLIBC_TUNABLES=glibc.cpu.hwcaps=-FMA gives the plain ones on any CPU). Our arithmetic is the same.
FLOOR_ANY_CPU, FLOOR_PLAIN_LIBM = 5e-6, 1e-6
MACHINE_NOISE_BOUND = 2.5e-5        # the noisy machine below jumps by about 1.1e-5 N.m between nearby speeds
PLAIN_LIBM = "glibc.cpu.hwcaps=-FMA"


def errors_by_K(Ks=(0, 10, 20)):
    table = wc.sweep(wc.load(CONFIG, T=0.02), Ks=list(Ks), certificates=False)
    return {row["K"]: row["max_error"] for row in table.rows}


def test_dr_converges_to_the_monolithic_reference_as_K_grows():
    """Max error over the first 20 steps of the start-up transient against the interface Newton,
    whose acceptance is relative to the port waves here (the FMUs' floor, above, on any CPU)."""
    errors = errors_by_K()
    assert errors[20] < errors[10] < errors[0] and errors[20] <= FLOOR_ANY_CPU and errors[0] > 1e-2, errors


@pytest.mark.slow
def test_the_floor_at_K_20_is_the_fmus_libm_not_ours():
    """With glibc's plain exp, log and pow (whatever the CPU), the floor is the tighter one."""
    code = ("import sys; sys.path.insert(0, {tests!r}); import test_dcmotor as t; print(t.errors_by_K((20,))[20])"
            .format(tests=str(ROOT / "tests")))
    env = {**os.environ, "GLIBC_TUNABLES": PLAIN_LIBM}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert float(out.stdout.split()[-1]) <= FLOOR_PLAIN_LIBM


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
    power-out. gamma: auto then finds a positive bound (about 6.3e-3) and DR meets the reference within
    the machine's own jumps: last bits anywhere (the coupling's compile, the FMUs' libm) move the error
    between 6e-6 and 1.4e-5, so the bound is MACHINE_NOISE_BOUND, about twice the jump."""
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
    assert s["status"] == "finished" and s["max_error"] <= MACHINE_NOISE_BOUND and s["fne_watch_ok"]
