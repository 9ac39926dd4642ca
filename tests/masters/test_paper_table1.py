"""The paper's experiment on Table I, through the real CLI: certificates, convergence, determinism."""
import csv
import json
import subprocess

import pytest
from paths import CLI

KS = [0, 3, 8, 20, 35, 50]


def wavecosim(*args, check=True):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True)
    if check and proc.returncode != 0:
        raise AssertionError(f"wavecosim {' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stderr}")
    return proc


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    wavecosim("sweep", "--Ks", ",".join(map(str, KS)), "--out", out, "--quiet")
    return out


@pytest.fixture(scope="module")
def runs(sweep_dir):
    data = json.loads((sweep_dir / "summary.json").read_text())
    return {r["K"]: r for r in data["runs"]}


def test_sweep_summary_has_every_budget_and_field(runs):
    assert sorted(runs) == KS
    for r in runs.values():
        for key in ("max_error", "rms_error", "final_error", "max_passivity_pos", "max_augmented_pos",
                    "min_fne_margin", "wall_time_s"):
            assert isinstance(r[key], float), key
        assert r["steps"] == 1000 and r["status"] == "finished"


def test_energy_certificates_at_roundoff_for_every_budget(runs):
    for K, r in runs.items():
        assert r["max_passivity_pos"] <= 1e-12, K        # Condition 2
        assert r["max_augmented_pos"] <= 1e-12, K        # Theorem 1
        assert r["min_fne_margin"] >= -1e-12, K          # Condition 1 at gamma = 0.4


def test_errors_fall_with_budget_to_the_monolithic_answer(runs):
    for metric in ("max_error", "rms_error", "final_error"):
        values = [runs[K][metric] for K in (8, 20, 35, 50)]
        assert all(a > b for a, b in zip(values, values[1:])), (metric, values)
    assert runs[50]["max_error"] <= 1e-10
    assert runs[20]["max_error"] <= 1e-3


def test_trajectory_files_have_the_documented_columns(sweep_dir):
    for name in ["monolithic", *[f"K{K}" for K in KS]]:
        with open(sweep_dir / f"trajectory_{name}.csv") as fh:
            rows = list(csv.reader(fh))
        assert rows[0] == ["time", "q1", "v1", "d", "q2", "v2", "bA", "bB"]
        assert len(rows) == 1002 and float(rows[1][0]) == 0.0 and float(rows[-1][0]) == pytest.approx(10.0)


def test_same_config_gives_bit_identical_output(tmp_path):
    for k in ("one", "two"):
        wavecosim("run", "--K", 8, "--T", 2, "--out", tmp_path / k, "--quiet")
    for name in ("trajectory.csv", "steps.csv"):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes()


def test_run_prints_table_and_writes_summary(tmp_path):
    proc = wavecosim("run", "--K", 20, "--T", 1, "--out", tmp_path, "--quiet")
    assert "max_error" in proc.stdout and "K=20" in proc.stdout
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["K"] == 20 and summary["steps"] == 100 and summary["max_passivity_pos"] <= 1e-12
