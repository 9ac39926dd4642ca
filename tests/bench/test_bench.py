"""`wavecosim bench --quick` runs every row and reports the whole-run ratios (a smoke test: the
figures themselves are measured, never asserted against the clock)."""
import json

import pytest

from wavecosim.cli import main


@pytest.mark.slow  # the bench smoke: every row of wavecosim bench --quick
def test_bench_quick_reports_every_path_and_the_run_over_master_ratio(tmp_path, capsys):
    try:
        main(["bench", "--quick", "--json", str(tmp_path / "b.json")])
    except SystemExit as exc:
        assert exc.code == 0
    out = capsys.readouterr().out
    data = json.loads((tmp_path / "b.json").read_text())
    assert data["fast_bit_identical_to_python"] is True
    for key in ("run_over_master", "run_over_master_certificates", "run_over_master_csv_files",
                "run_over_master_certificates_csv_files"):
        assert set(data[key]) == {"K0", "K50"} and all(v > 0 for v in data[key].values())
    assert {k for k in data["targets"] if k.startswith("run / master")} == {
        f"run / master <= {x}, {where}" for x in ("1.5", "3 with certificates")
        for where in ("run() default: rows in memory", "CSV files")}
    assert set(data["us_per_step"]) == {"naive_fmpy", "python", "fast_step", "fast", "floor"}
    adapter = data["wave_adapter"]["foreign_pair"]
    assert adapter["bit_identical"] is True and "wave adapter" in out
    assert adapter["c"]["doSteps_per_evaluation"] == adapter["python"]["doSteps_per_evaluation"] <= 1.3
    assert "whole run" in out and "fast / floor" in out and "deadline bound" in out
    bound = data["deadline_bound"]
    assert list(bound) == ["star", "star, certificates", "heavy_chain", "heavy_chain, certificates"]
    assert [b["deadline_us"] for b in bound.values()] == [30.0, 30.0, 1500.0, 1500.0]
    assert [b["block_steps"] == b["steps"] for b in bound.values()] == [True] * 4   # certificates in the blocks (certs.c)
    assert all(b["bound_us"] == b["deadline_us"] + b["round_us"] and {"median", "p99", "max"} <= set(b["all_us"])
               for b in bound.values())
    assert set(data["us_per_subsystem_iter"]) == {"8", "64", "512"} and all(v > 0 for v in data["us_per_subsystem_iter"].values())
    assert set(data["classical_kernel"]["masters"]) == {"explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter"}
    assert "chain of N" in out and "classical masters" in out
    assert set(data["newton_kernel"]["scenes"]) == {"Table I", "stiff"} and "newton, " in out
