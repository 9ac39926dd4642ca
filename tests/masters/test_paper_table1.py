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


# The authors' C++ on Table I (V7CN/wave-domain-iterative-coupling, commit 7bed44a,
# examples/two_oscillators_duffing_linear/out_cpp/summary.json): max, rms and final error per K.
AUTHORS = {0: (0.69095521338103272, 0.36961247194385299, 0.42338875258276137),
           3: (0.7959707928536065, 0.34369914882094887, 0.72173115382455832),
           8: (0.20220914189631148, 0.079635323034434727, 0.1882768646166518),
           20: (0.00021952422973319438, 8.4531991286621494e-05, 0.00014338024952904516),
           35: (7.6980084159439148e-08, 3.0132046723962537e-08, 5.1752516295262429e-08),
           50: (1.1959408167018605e-11, 4.7778382748181095e-12, 8.3118322879782266e-12)}


def test_guard_off_is_the_paper_and_matches_the_authors_to_1e_9():
    """energy_guard: off runs Algorithm 1 as printed (start P b^n, no ledger): every error of the
    authors' Table I to 1e-9."""
    import wavecosim as wc
    table = wc.sweep(wc.load().with_master(energy_guard="off"), Ks=KS, certificates=False)
    runs = {r["K"]: r for r in table.rows}
    for K, figures in AUTHORS.items():
        assert runs[K]["start"] == "paper" and runs[K]["energy_guard"] == "off"
        ours = (runs[K]["max_error"], runs[K]["rms_error"], runs[K]["final_error"])
        assert all(abs(a - b) <= 1e-9 for a, b in zip(ours, figures)), (K, ours, figures)
