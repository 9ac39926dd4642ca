"""Sweep tasks on every executor (serial, a spawn process pool, a real Dask LocalCluster), on the real FMUs."""
import csv
import re
from pathlib import Path

import pytest

from paths import ROOT
from wavecosim.errors import ConfigError
from wavecosim.sweeps.execute import dask, process_pool, serial
from wavecosim.scenario.overrides import apply_overrides, expand, parse_set, short_label
from wavecosim.sweeps.budget import plan, run_sweep

TABLE_I = ROOT / "configs" / "two_oscillators.yaml"
TIMES = ("task_time_s", "wall_time_s", "total_time_s", "loop_time_s", "real_time_factor")
GRID = [("master.K", [0, 8]), ("subsystems.B.parameters.k2", [50.0, 80.0])]


def figures(rows):
    """Rows without the timings (which differ from run to run)."""
    return [{k: v for k, v in row.items() if k not in TIMES} for row in rows]


def trajectories(tasks):
    return [(Path(t.out_dir) / "trajectory.csv").read_bytes() for t in tasks]


def run_with(executor, out):
    tasks = plan(TABLE_I, GRID, out, fixed=[("T", 0.2)])
    rows = {row["index"]: row for row in executor(tasks)}
    return tasks, [rows[i] for i in sorted(rows)]


@pytest.fixture(scope="module")
def serial_rows(tmp_path_factory):
    return run_with(serial, tmp_path_factory.mktemp("serial"))


def test_serial_rows_follow_the_grid_and_the_runs_use_the_values(serial_rows):
    tasks, rows = serial_rows
    assert [(r["master.K"], r["subsystems.B.parameters.k2"]) for r in rows] == [(0, 50.0), (0, 80.0), (8, 50.0), (8, 80.0)]
    assert all(r["status"] == "finished" and r["steps"] == 20 and r["threads"] == 1 for r in rows)
    assert [r["K"] for r in rows] == [0, 0, 8, 8]
    assert len({r["max_error"] for r in rows}) == 4               # k2 changes the physics
    assert rows[2]["max_error"] < rows[0]["max_error"]            # K = 8 beats K = 0 at k2 = 50
    assert [Path(t.out_dir).name for t in tasks] == ["0_K-0_k2-50", "1_K-0_k2-80", "2_K-8_k2-50", "3_K-8_k2-80"]


def test_process_pool_of_two_gives_the_serial_numbers_bit_for_bit(serial_rows, tmp_path):
    tasks, rows = run_with(lambda t: process_pool(t, 2), tmp_path)
    assert figures(rows) == figures(serial_rows[1])
    assert trajectories(tasks) == trajectories(serial_rows[0])


@pytest.mark.slow  # starts a Dask LocalCluster
def test_dask_local_cluster_of_two_processes_gives_the_serial_numbers_bit_for_bit(serial_rows, tmp_path):
    tasks, rows = run_with(lambda t: dask(t, "local", 2), tmp_path)
    assert figures(rows) == figures(serial_rows[1])
    assert trajectories(tasks) == trajectories(serial_rows[0])


def test_monte_carlo_over_two_subsystems_is_seeded_and_the_runs_start_from_the_draws(tmp_path):
    axes = [("subsystems.A.start.q1", ("uniform", 0.1, 0.5)), ("subsystems.B.parameters.m2", ("normal", 4.0, 0.1))]
    tasks = plan(TABLE_I, axes, tmp_path, fixed=[("T", 0.1)], sample=3, seed=7)
    assert [t.overrides for t in tasks] == [t.overrides for t in plan(TABLE_I, axes, tmp_path, [("T", 0.1)], 3, 7)]
    assert [t.overrides for t in tasks] != [t.overrides for t in plan(TABLE_I, axes, tmp_path, [("T", 0.1)], 3, 8)]
    rows = run_sweep(tasks, tmp_path, {}, workers=1)
    q1 = [r["subsystems.A.start.q1"] for r in rows]
    assert len(set(q1)) == 3 and all(0.1 <= q <= 0.5 for q in q1)
    assert all(abs(r["subsystems.B.parameters.m2"] - 4.0) < 1.0 for r in rows)
    for task, row in zip(tasks, rows):
        with open(Path(task.out_dir) / "trajectory.csv") as fh:
            first = next(r for r in csv.DictReader(fh))
        assert float(first["q1"]) == row["subsystems.A.start.q1"]
    saved = list(csv.DictReader(open(tmp_path / "runs.csv")))
    assert [float(r["subsystems.A.start.q1"]) for r in saved] == q1        # repr round-trips exactly


def test_a_grid_is_crossed_with_the_samples():
    points = expand([("master.K", [0, 3]), ("T", ("uniform", 1.0, 2.0))], sample=2, seed=1)
    assert [p[0] for p in points] == [("master.K", 0)] * 2 + [("master.K", 3)] * 2
    assert [p[1][1] for p in points[:2]] == [p[1][1] for p in points[2:]]


@pytest.mark.parametrize("text, values", [
    ("master.K=0,3,8", [0, 3, 8]), ("master.K=0..3,8", [0, 1, 2, 3, 8]), ("T=1e3", [1000.0]),
    ("gamma=auto", ["auto"]), ("master.energy_guard=false", [False]), ("master.eps=null", [None]),
    ("x=linspace(0,1,3)", [0.0, 0.5, 1.0]), ("x=geomspace(1,100,3)", [1.0, 10.0, 100.0]),
    ("x=normal(1,0.5)", ("normal", 1, 0.5))])
def test_set_syntax(text, values):
    key, parsed = parse_set(text)
    assert key == text.split("=")[0]
    assert parsed == (pytest.approx(values) if isinstance(values, list) else values)


@pytest.mark.parametrize("text, words", [
    ("master.K", "must be KEY=VALUES"), ("a..b=1", "not a key path"), ("x=uniform(1)", "takes 2 numbers"),
    ("x=foo(1,2)", "unknown function foo()"), ("x=3..1", "empty range"), ("x=1,uniform(0,1)", "stands alone")])
def test_bad_set_options_are_one_line_errors(text, words):
    with pytest.raises(ConfigError) as exc:
        parse_set(text)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_overrides_set_nested_keys_and_refuse_unknown_places():
    raw = {"master": {"K": 1}, "subsystems": {"A": {"fmu": "X"}}, "couplings": [{"type": "t"}]}
    out = apply_overrides(raw, [("master.K", 5), ("subsystems.A.parameters.k", 2.0), ("couplings[0].ratio", 3)])
    assert out["master"]["K"] == 5 and out["subsystems"]["A"]["parameters"] == {"k": 2.0}
    assert out["couplings"][0]["ratio"] == 3 and raw["master"]["K"] == 1          # the original is untouched
    for key, words in (("subsystems.Z.start.q", "no 'Z'"), ("couplings[2].ratio", "no list entry [2]"),
                       ("master.K.x", "not a mapping")):
        with pytest.raises(ConfigError, match=re.escape(words)):
            apply_overrides(raw, [(key, 1)])
    assert short_label([("subsystems.A.start.q1", 0.123456), ("master.K", 3)]) == "q1-0.1235_K-3"
