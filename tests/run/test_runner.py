"""master/runner.py: the run as parts. The time column is the grid, an output interval thins the
files but not the figures, the lockstep reference gives the same errors as a stored one, the
metadata names the FMUs by checksum, and every failure keeps its class (and exit code). Runs made in
blocks of macro-steps (one kernel call each) write the same bytes and figures as step by step."""
import copy
import csv
import dataclasses
import hashlib
import json

import numpy as np
import pytest
import yaml
from scipy.io import loadmat
from test_runner_failures import newton_failure

from paths import ROOT
import wavecosim.run.live as live
import wavecosim.run.runner as runner
from wavecosim.sweeps.budget import reference_run
from wavecosim.cli import main
from wavecosim.scenario.config import load_scenario
from wavecosim.errors import FmuError, NumericalError, RunFailed
from wavecosim.run.observers.errors import ErrorTracker
from wavecosim.core.readings import BlockReading, Reading, row_sums
from wavecosim.kernel.linalg import total
from wavecosim.run.runner import grid_times, run


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


# ---- block mode: many macro-steps per call of the C kernel, the same files and figures ----

TIMING = {"wall_time_s", "total_time_s", "loop_time_s", "real_time_factor", "thread_note", "block_steps"}


def step_by_step(monkeypatch, scenario, out, block=runner.BLOCK_STEPS, **options):
    """The run with blocks of one step (the per-step path), then with blocks of `block` steps."""
    results = []
    for size, kind in ((1, "steps"), (block, "blocks")):
        with monkeypatch.context() as m:
            m.setattr(live, "BLOCK_STEPS", size)
            results.append(run(scenario, out / kind, certificates=False, file_suffix=False, **options))
    return results


def same_files_and_figures(one, blocks, out, names=("trajectory.csv", "steps.csv")):
    for name in names:
        assert (out / "steps" / name).read_bytes() == (out / "blocks" / name).read_bytes(), name
    same_figures(one, blocks)
    assert one.summary["block_steps"] == 0 and blocks.summary["block_steps"] > 0


def same_figures(one, blocks):
    """The summaries alike but for their times, and the blocks' FMU value gets: with the monolithic
    guard, which reads H apart after each step made alone, fewer (the kernel reads H once, with the
    run's values)."""
    a, b = (copy.deepcopy({k: v for k, v in r.summary.items() if k not in TIMING}) for r in (one, blocks))
    if a.get("energy_guard") == "monolithic":
        assert b["fmu_calls"]["get"] < a["fmu_calls"]["get"]
        for summary in (a, b):
            for calls in (summary["fmu_calls"], *summary["fmu_calls_by_subsystem"].values()):
                calls.pop("get")
    assert json.dumps(a, default=str) == json.dumps(b, default=str)


@pytest.mark.parametrize("K,guard,guarded", [(0, "monolithic", 0), (1, "monolithic", 0), (8, "monolithic", 3),
                                             (50, "monolithic", 0), (0, "ledger", 0), (8, "ledger", 112)])
def test_blocks_give_the_step_by_step_files(tmp_path, monkeypatch, K, guard, guarded):
    """Table I, 1000 steps: at K = 8 the monolithic guard redoes 3 steps, each stopping a block, and
    the ledger 112 (the kernel keeps the ledger and makes its redo itself, inside the block)."""
    one, blocks = step_by_step(monkeypatch, load_scenario().with_master(K=K, energy_guard=guard), tmp_path)
    same_files_and_figures(one, blocks, tmp_path)
    assert blocks.summary["energy_guard_steps"] == guarded
    assert blocks.summary["block_steps"] == 1000


def test_a_guarded_step_ending_a_block(tmp_path, monkeypatch):
    """At K = 8 the guard redoes steps 0, 25 and 52; blocks of 25 (steps 1..25, 26..50, ...) end on step 25."""
    one, blocks = step_by_step(monkeypatch, load_scenario().with_master(K=8, energy_guard="monolithic")
                               .with_changes(T=1.0), tmp_path, 25)
    same_files_and_figures(one, blocks, tmp_path)
    assert blocks.summary["energy_guard_steps"] == 3
    assert [int(k) for k in np.flatnonzero(blocks.steps["iterations"] != 8)] == [0, 25, 52]


def test_blocks_with_output_interval_tolerance_and_lockstep_errors(tmp_path, monkeypatch):
    scenario = load_scenario().with_master(K=50, eps=1e-9).with_changes(T=3.0)
    one, blocks = step_by_step(monkeypatch, scenario, tmp_path, output_interval=7, reference="lockstep")
    same_files_and_figures(one, blocks, tmp_path, ("trajectory.csv", "steps.csv", "trajectory_monolithic.csv",
                                                   "steps_monolithic.csv"))
    assert min(blocks.steps["iterations"]) < 50 and blocks.summary["max_error"] > 0


def test_blocks_on_the_star_scene(tmp_path, monkeypatch):
    """Four subsystems, a gamma each, outputs from all of them, stored-reference errors."""
    scenario = load_scenario(ROOT / "configs" / "star.yaml").with_master(K=10)
    reference = run(scenario.with_master(algorithm="newton"), certificates=False)
    one, blocks = step_by_step(monkeypatch, scenario, tmp_path, reference=reference)
    same_files_and_figures(one, blocks, tmp_path)
    assert np.isfinite(blocks.summary["rms_error"])


def test_blocks_keep_every_row_before_an_fmu_failure(tmp_path, monkeypatch):
    """DuffingSide's Newton fails at step 18 inside a block: rows 0..17 on disk, exit code 3."""
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(newton_failure(), sort_keys=False))
    for kind, size in (("steps", 1), ("blocks", runner.BLOCK_STEPS)):
        with monkeypatch.context() as m, pytest.raises(SystemExit) as info:
            m.setattr(live, "BLOCK_STEPS", size)
            main(["run", str(path), "--out", str(tmp_path / kind), "--quiet", "--no-reference", "--no-certificates"])
        assert info.value.code == 3
    for name in ("trajectory.csv", "steps.csv"):
        assert (tmp_path / "steps" / name).read_bytes() == (tmp_path / "blocks" / name).read_bytes()
    summary = json.loads((tmp_path / "blocks" / "summary.json").read_text())
    assert summary["steps"] == 18 and summary["block_steps"] == 18
    assert len(read_csv(tmp_path / "blocks" / "steps.csv")) == 19
    assert summary["message"].startswith("subsystem A: fmi2DoStep returned Error at step 18 (t = 0.18)")


def test_block_sums_are_the_step_sums():
    """row_sums (H_total, port energies) and the block error norm give the per-step bits (linalg.total,
    left to right, whatever the Python: builtin sum() compensates from 3.12 on), also where the order of
    summation shows (1e16 + 1 + 1) and for many error columns (numpy's pairwise sum)."""
    rng = np.random.default_rng(3)
    X = rng.standard_normal((200, 9)) * 10.0 ** rng.integers(-8, 17, (200, 9))
    X[0, :3] = [1e16, 1.0, 1.0]
    assert row_sums(X).tolist() == [total(r) for r in X.tolist()]
    assert total([1e16, 1.0, 1.0]) == 1e16
    assert row_sums(X[:1, :3])[0] != 1e16 + (1.0 + 1.0)
    ref = rng.standard_normal((201, 12))
    out = X @ rng.standard_normal((9, 12))
    names = [f"c{j}" for j in range(12)]
    for n_err in (2, 3, 5, 7, 8, 9, 12):
        step, block = (ErrorTracker(names, names[:n_err], lambda k: ref[k].tolist()) for _ in range(2))
        rows, block_rows = np.empty((200, 1)), np.empty((200, 1))
        for n in range(200):
            step.after_step(n, n * 0.01, None, Reading([], [], [], [], out[n].tolist()), rows[n])
        block.after_block(0, None, BlockReading(out.T, {"outputs": list(range(12))}), block_rows)
        assert rows.tobytes() == block_rows.tobytes(), n_err
        assert step.summary() == block.summary()


def test_blocks_cut_to_the_time_budget(tmp_path, monkeypatch):
    """A call of run_steps makes about BLOCK_SECONDS of work at most (Ctrl-C and progress stay
    prompt); short blocks give the same files."""
    from wavecosim.masters import dr_route
    made, run_steps = [], dr_route.DRRoute.run_steps

    def counted(route, n0, count, H_cap=None, passes=False):
        result = run_steps(route, n0, count, H_cap, passes)
        made.append(result[0])
        return result
    monkeypatch.setattr(dr_route.DRRoute, "run_steps", counted)
    monkeypatch.setattr(dr_route, "BLOCK_SECONDS", 2e-4)
    one, blocks = step_by_step(monkeypatch, load_scenario().with_master(K=50).with_changes(T=3.0), tmp_path)
    same_files_and_figures(one, blocks, tmp_path)
    assert len(made) > 3 and max(made) < 300 and sum(made) == blocks.summary["block_steps"] == 300


def test_a_last_single_step_is_a_block_too(tmp_path, monkeypatch):
    """Blocks of 3 over 10 steps: the last step, alone, is still made by the kernel's route (a block of
    one), so how blocks are cut never moves a step out of them; the files are the step-by-step ones."""
    scenario = load_scenario().with_changes(T=10 * load_scenario().dt)
    one, blocks = step_by_step(monkeypatch, scenario, tmp_path, block=3)
    same_files_and_figures(one, blocks, tmp_path)
    assert blocks.summary["steps"] == 10 and blocks.summary["block_steps"] == 10


def test_blocks_on_a_grid_of_k_dt(tmp_path, monkeypatch):
    """1/dt not a whole number: the grid is k * dt, in blocks (kernel/c/blocks.c) as step by step."""
    scenario = load_scenario().with_changes(dt=0.003, T=0.9)
    one, blocks = step_by_step(monkeypatch, scenario, tmp_path)
    same_files_and_figures(one, blocks, tmp_path)
    assert runner.grid_inverse(0.003) == 0 and blocks.summary["block_steps"] == 300
    assert blocks.trajectory["time"].tolist() == [k * 0.003 for k in range(301)]


@pytest.mark.parametrize("K, every, guard, blocked, block", [(0, "auto", "ledger", 1000, 1024), (1, 3, "ledger", 1000, 1024),
                                                            (3, "auto", "ledger", 1000, 1024), (50, 1, "ledger", 1000, 1024),
                                                            (8, 1, "monolithic", 1000, 1024), (8, "auto", "off", 1000, 1024),
                                                            (1, 3, "ledger", 1000, 7), (0, "auto", "ledger", 1000, 7)])
def test_blocks_with_certificates(tmp_path, monkeypatch, K, every, guard, blocked, block):
    """Certificates on, sampled every `every` steps, with the step-by-step files and figures: the
    kernel computes them inside the blocks (certs.c; at K < 2 the watch's probe of one-channel ports),
    also on steps the monolithic guard judges after their block (K = 8: steps 0, 25 and 52 redone);
    blocks of 7 steps start between sampled steps (n0 % every != 0)."""
    sc = load_scenario().with_master(K=K, energy_guard=guard)
    sc = dataclasses.replace(sc, certificates=dataclasses.replace(sc.certificates, every=every))
    results = []
    for size, kind in ((1, "steps"), (block, "blocks")):
        with monkeypatch.context() as m:
            m.setattr(live, "BLOCK_STEPS", size)
            results.append(run(sc, tmp_path / kind, file_suffix=False))
    one, blocks = results
    for name in ("trajectory.csv", "steps.csv"):
        assert (tmp_path / "steps" / name).read_bytes() == (tmp_path / "blocks" / name).read_bytes(), name
    same_figures(one, blocks)
    assert blocks.summary["block_steps"] == blocked and one.summary["block_steps"] == 0
    assert np.isfinite(blocks.steps["fne_A"]).sum() == -(-1000 // blocks.summary["certificates_every"])
    assert blocks.summary.get("energy_guard_steps") == {"ledger": blocks.summary.get("energy_guard_steps"), "monolithic": 3, "off": None}[guard]
