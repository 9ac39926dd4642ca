"""The SSP systems of ../shared/third_party (skipped when it is absent) run as a user runs them,
`wavecosim run <folder>/SystemStructure.ssd` and no other flag, and give what OMSimulator prints
for them (its README); the compatibility script's rows pass."""
import importlib.util
import math
import subprocess

import numpy as np
import pytest

from paths import CLI, ROOT, THIRD_PARTY

OMS = THIRD_PARTY / "omsimulator"
pytestmark = pytest.mark.skipif(not OMS.exists(), reason="the third-party systems (../shared/third_party) are absent")


def compatibility():
    """scripts/compatibility.py as a module (its plain fmpy loop and its rows)."""
    spec = importlib.util.spec_from_file_location("compatibility", ROOT / "scripts" / "compatibility.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run(tmp_path, *args):
    """`wavecosim run ARGS --quiet --out tmp`: (exit code, stderr, the trajectory as a structured array)."""
    proc = subprocess.run([*CLI, "run", *map(str, args), "--quiet", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=900)
    csv = tmp_path / "out" / "trajectory.csv"
    traj = np.genfromtxt(csv, delimiter=",", names=True, deletechars="", dtype=float) if csv.exists() else None
    return proc.returncode, proc.stderr, traj


PRINTED = {   # OMSimulator's values at the end of the run (for import_export_parameters1: its semantics,
              # connector values over component bindings, with this folder's .ssv)
    "LinearTransformation": {"Gain1.y": 0.0, "Add1.u1": 3.0},
    "LinearTransformation3": {"Gain1.y": 182.0, "Add1.u1": 182.0},
    "import_export_parameters1": {"addP.k1": 30.0, "addI.k2": 20.0, "addP.u1": -20.0, "addP.y": -600.0,
                                  "Output_cref": -600.0},
}


@pytest.mark.parametrize("folder", list(PRINTED))
def test_an_omsimulator_system_runs_with_the_file_alone_and_gives_its_printed_values(tmp_path, folder):
    code, err, traj = run(tmp_path, OMS / folder / "SystemStructure.ssd")
    assert code == 0, err
    assert {col: float(traj[col][-1]) for col in PRINTED[folder]} == PRINTED[folder]


def test_pwmtest_builds_its_source_fmus_and_integrates_the_model_exchange_circuit(tmp_path):
    """Both FMUs ship win64 binaries and their sources: built here; the circuit has model exchange only.
    Its current meets the exact response of L di/dt = -(R i + u) to the pulse held over each step."""
    code, err, traj = run(tmp_path, OMS / "pwmtest" / "SystemStructure.ssd")
    assert code == 0, err
    assert len(traj) == 1001 and "SCSystem.u" in traj.dtype.names         # a nested system's connector, recorded
    R, L, dt = traj["circuit.resistor.R"][0], traj["circuit.inductor.L"][0], 0.001
    decay, current = math.exp(-R * dt / L), np.zeros(len(traj))
    for n in range(len(traj) - 1):
        current[n + 1] = current[n] * decay - traj["circuit.u"][n + 1] / R * (1 - decay)
    assert np.max(np.abs(traj["circuit.inductor.i"] - current)) < 1e-4 * np.max(np.abs(current))
    assert np.array_equal(traj["circuit.u"][1:], traj["pulse.y"][:-1])           # held over each step


@pytest.mark.slow
def test_embrace_runs_a_second_with_the_pipe_lengths_its_mapping_gives(tmp_path):
    code, err, traj = run(tmp_path, OMS / "embrace" / "SystemStructure.ssd", "--T", "1")
    assert code == 0, err
    assert traj["ECS_HW.pipeA.L"][0] == traj["ECS_HW.pipeB.L"][0] == 0.976535328081166
    assert len(traj) == 1001 and np.all(np.isfinite(traj["ECS_HW.LHexTout"]))


def test_the_dcmotor_runs_with_the_file_alone(tmp_path):
    """No DefaultExperiment and no step size anywhere: T from the FMUs, dt by fmpy's rule (said in a
    warning); no power bond: the explicit master."""
    code, err, traj = run(tmp_path, THIRD_PARTY / "dcmotor" / "SystemStructure.ssd")
    assert code == 0, err
    assert "SystemStructure.ssd: dt = 0.002 (fmpy's default for a run of 1 s: 500 steps" in err
    assert traj.dtype.names == ("time", "M_mot", "wB", "U", "I", "M_load") and len(traj) == 501
    assert traj["wB"][-1] > 50.0                                # the motor has run up against its load


def test_the_dual_mass_oscillator_runs_explicit_and_a_rollback_master_refuses_it(tmp_path):
    """FMUs that cannot save their state: the explicit master runs them as a plain fmpy loop does;
    DR on their force/velocity pair (declared with --ports) is refused in one line."""
    compat = compatibility()
    path = compat.dual_mass_ssd(THIRD_PARTY, tmp_path)
    scenario, _ = compat.load(path, outputs={"x1": "system1.x1", "x2": "system2.x2"}, T=0.05, dt=1e-4)
    result, _ = compat.simulate(scenario)
    assert compat.same_as_plain_loop(scenario, result)[0]
    (tmp_path / "ports.yaml").write_text(compat.DMO_PORTS)
    code, err, _ = run(tmp_path, path, "--ports", tmp_path / "ports.yaml", "--master", "dr", "--T", "0.01")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "DualMassOscillator.System" in err and "cannot get and set its state" in err


@pytest.mark.slow
def test_the_compatibility_script_writes_its_rows(tmp_path):
    """The script's quick rows pass (the whole table: tests marked slow)."""
    text, passed = compatibility().table(THIRD_PARTY, only="LinearTransformation", progress=lambda m: None)
    assert passed and text.count("| OK: ") == 2, text


@pytest.mark.slow
def test_every_row_of_the_compatibility_table_passes():
    text, passed = compatibility().table(THIRD_PARTY, progress=lambda m: None)
    assert passed, text
