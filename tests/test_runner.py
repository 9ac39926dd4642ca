"""master/runner.py: the run as parts. The time column is the grid, an output interval thins the
files but not the figures, the lockstep reference gives the same errors as a stored one, the
metadata names the FMUs by checksum, and every failure keeps its class (and exit code)."""
import csv
import hashlib
import json

import numpy as np
import pytest
from scipy.io import loadmat

from wavecosim.config import load_scenario
from wavecosim.errors import FmuError, NumericalError, RunFailed
from wavecosim.runner import grid_times, run
from wavecosim.budget_sweep import reference_run


@pytest.fixture(scope="module")
def table_i():
    return load_scenario().with_changes(T=1.0)


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))


def test_time_column_holds_grid_values(tmp_path, table_i):
    run(table_i.with_master(K=3), tmp_path, certificates=False, file_suffix=False)
    rows = read_csv(tmp_path / "trajectory.csv")
    assert rows[0][0] == "time" and rows[31][0] == "0.3" and rows[-1][0] == "1.0"
    assert read_csv(tmp_path / "steps.csv")[30][0] == "0.3"
    assert grid_times(np.arange(4), 0.1).tolist() == [0.0, 0.1, 0.2, 0.3]               # not 0.30000000000000004
    assert grid_times(np.arange(4), 0.003).tolist() == (np.arange(4) * 0.003).tolist()  # no whole 1/dt


def test_output_interval_thins_the_files_not_the_figures(tmp_path, table_i):
    every = run(table_i.with_master(K=8), tmp_path / "a", certificates=False, file_suffix=False,
                reference="lockstep")
    tenth = run(table_i.with_master(K=8), tmp_path / "b", certificates=False, file_suffix=False,
                reference="lockstep", output_interval=7)
    for key in ("max_error", "rms_error", "final_error", "max_passivity_pos", "H_final", "fmu_calls"):
        assert every.summary[key] == tenth.summary[key], key
    kept = read_csv(tmp_path / "b" / "trajectory.csv")[1:]
    assert [r[0] for r in kept] == [repr(t) for t in grid_times(np.r_[np.arange(0, 100, 7), 100], 0.01).tolist()]
    assert np.array_equal(tenth.outputs, every.outputs[np.r_[np.arange(0, 100, 7), 100]])


def test_lockstep_reference_gives_the_stored_reference_errors(tmp_path, table_i):
    sc = table_i.with_master(K=8)
    stored = run(sc, certificates=False, reference=reference_run(sc))
    lockstep = run(sc, tmp_path, certificates=False, reference="lockstep", file_suffix=False)
    for key in ("max_error", "final_error"):
        assert stored.summary[key] == lockstep.summary[key]
    assert np.array_equal(stored.error, lockstep.error)
    assert lockstep.reference.summary["master"] == "newton"
    assert (tmp_path / "trajectory_monolithic.csv").exists() and (tmp_path / "summary_monolithic.json").exists()


def test_metadata_and_mat_files(tmp_path, table_i):
    result = run(table_i.with_master(K=0), tmp_path, certificates=False, file_suffix=False, formats=("csv", "mat"))
    meta = json.loads((tmp_path / "metadata.json").read_text())
    for name, fmu in meta["fmus"].items():
        assert fmu["sha256"] == hashlib.sha256(open(fmu["path"], "rb").read()).hexdigest()
    assert meta["scenario"]["master"]["K"] == 0 and meta["versions"]["numpy"] == np.__version__
    mat = loadmat(str(tmp_path / "trajectory.mat"))
    assert np.array_equal(mat["q1"].ravel(), result.column("q1"))


def test_failures_keep_their_class_and_exit_code():
    """RunFailed takes the exit code of the exception that stopped the run: 3 for an FMU's own
    error, 4 for a numerical failure of the master (the code used to be guessed from the message)."""
    assert RunFailed(FmuError("Newton step did not converge"), None).exit_code == 3
    assert RunFailed(NumericalError("FMU returned an Error"), None).exit_code == 4


def test_result_arrays_match_the_files(tmp_path, table_i):
    result = run(table_i.with_master(K=3), tmp_path, file_suffix=False)
    steps = read_csv(tmp_path / "steps.csv")
    cols = steps[0]
    H = [float(r[cols.index("H_total")]) for r in steps[1:]]
    assert result.energy[1:].tolist() == H and len(result.energy) == 101
    assert result.per_subsystem("r_").shape == (100, 2) and result.per_subsystem("fne_").shape == (100, 2)
    assert [r[cols.index("reason")] for r in steps[1:]] == ["budget"] * 100
