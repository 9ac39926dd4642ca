"""`wavecosim sweep` through the real CLI: general sweeps, bad input, failing runs, resume, plots."""
import csv
import json

import pytest

from paths import ROOT
from wavecosim.cli import main, parse_budgets
from wavecosim.errors import ConfigError

TABLE_I = str(ROOT / "configs" / "two_oscillators.yaml")
PNG = b"\x89PNG\r\n\x1a\n"
FAILING = ["--set", "subsystems.A.integers.newton_max_iter=4,50", "--set", "subsystems.A.start.q1=2",
           "--set", "subsystems.A.start.d=-2"]


def sweep(capsys, out, *args):
    """(exit code, stdout, stderr) of `wavecosim sweep TABLE_I --out OUT ARGS`."""
    with pytest.raises(SystemExit) as exc:
        main(["sweep", TABLE_I, "--out", str(out), *map(str, args)])
    captured = capsys.readouterr()
    return exc.value.code, captured.out, captured.err


def rows_of(out):
    with open(out / "runs.csv") as fh:
        return list(csv.DictReader(fh))


def test_grid_over_two_subsystems_writes_one_row_and_one_folder_per_run(tmp_path, capsys):
    code, printed, err = sweep(capsys, tmp_path, "--K", "0,8", "--set", "subsystems.A.parameters.k12=120,1200",
                               "--set", "subsystems.B.start.q2=0.1", "--T", "0.2", "--workers", "1", "--plots")
    assert code == 0 and "4 runs (0 not finished)" in printed
    rows = rows_of(tmp_path)
    assert [(r["master.K"], r["subsystems.A.parameters.k12"]) for r in rows] == [
        ("0", "120"), ("0", "1200"), ("8", "120"), ("8", "1200")]
    assert all(r["status"] == "finished" and float(r["max_error"]) > 0 and float(r["task_time_s"]) > 0 for r in rows)
    saved = json.loads((tmp_path / "runs.json").read_text())
    assert [r["label"] for r in saved["runs"]] == [r["label"] for r in rows]
    for r in saved["runs"]:
        folder = tmp_path / "runs" / r["label"]
        assert json.loads((folder / "summary.json").read_text())["max_error"] == r["max_error"]
        assert (folder / "trajectory.csv").exists() and (folder / "steps_monolithic.csv").exists()
    assert "ETA" in err and "4/4 runs" in err
    assert (tmp_path / "max_error_vs_master.K.png").read_bytes()[:8] == PNG


@pytest.mark.parametrize("args, words", [
    (["--set", "master.KK=1"], "master.KK: unknown key"),
    (["--set", "subsystems.C.parameters.k=1"], "subsystems.C.parameters.k: no 'C'"),
    (["--set", "subsystems.A.parameters.k99=1,2"], "subsystems.A.parameters.k99: A: the FMU DuffingSide.fmu has no"),
    (["--set", "master.K=0,-1"], "master.K: must be >= 0, got -1"),
    (["--set", "subsystems.B.parameters.m2=heavy"], "subsystems.B.parameters.m2: B: m2 is a Real variable of LinearSide.fmu; got 'heavy'"),
    (["--set", "subsystems.A.start.q1=uniform(0.1,0.5)"], "give --sample N"),
    (["--sample", "3"], "--sample: needs at least one"),
    (["--K", "0,x", "--workers", "1"], "--K: must be comma-separated integers"),
    (["--K", "0,1", "--set", "master.K=2"], "--set master.K: given twice"),
    (["--set", "subsystems.B.parameters.m2=normal(4,-1)", "--sample", "2"], "normal(4,-1) needs sigma >= 0")])
def test_bad_keys_and_values_stop_before_anything_runs(tmp_path, capsys, args, words):
    code, printed, err = sweep(capsys, tmp_path / "out", "--T", "0.2", *args)
    assert code == 2
    assert words in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "out").exists()


def test_a_failing_run_is_a_row_and_the_sweep_goes_on(tmp_path, capsys):
    code, printed, _ = sweep(capsys, tmp_path, *FAILING, "--T", "0.3", "--workers", "2", "--no-reference", "--quiet")
    assert code == 0
    failed, finished = rows_of(tmp_path)
    assert failed["status"] == "failed" and finished["status"] == "finished"
    assert "at step 18" in failed["message"] and "did not converge in 4 iterations" in failed["message"]
    assert failed["steps"] == "18" and finished["steps"] == "30"
    assert "run 0" in printed and "failed" in printed


def test_resume_skips_finished_runs(tmp_path, capsys):
    args = ["--set", "master.K=0,3,8", "--T", "0.2", "--workers", "1"]
    sweep(capsys, tmp_path, *args, "--quiet")
    first = {r["label"]: r for r in rows_of(tmp_path)}
    redo = tmp_path / "runs" / "1_K-3"
    (redo / "summary.json").write_text(json.dumps({"status": "interrupted"}))
    code, _, err = sweep(capsys, tmp_path, *args, "--resume")
    assert code == 0 and "3/3 runs (2 resumed" in err and err.count("sweep:") == 1
    again = {r["label"]: r for r in rows_of(tmp_path)}
    assert again["0_K-0"] == first["0_K-0"] and again["2_K-8"] == first["2_K-8"]        # read back, not rerun
    assert again["1_K-3"]["max_error"] == first["1_K-3"]["max_error"]
    assert again["1_K-3"]["task_time_s"] != first["1_K-3"]["task_time_s"]                # this one ran again
    assert json.loads((redo / "summary.json").read_text())["status"] == "finished"


def test_default_sweep_takes_a_K_list_and_keeps_Ks_as_an_alias(tmp_path, capsys):
    summaries = []
    for option in ("--K", "--Ks"):
        code, printed, _ = sweep(capsys, tmp_path / option, option, "0,8", "--T", "0.5", "--quiet")
        assert code == 0 and "sweep over K = [0, 8]" in printed
        summaries.append(json.loads((tmp_path / option / "summary.json").read_text()))
    keys = ("K", "max_error", "rms_error", "final_error", "max_passivity_pos", "min_fne_margin")
    assert [[r[k] for k in keys] for r in summaries[0]["runs"]] == [[r[k] for k in keys] for r in summaries[1]["runs"]]
    assert [r["K"] for r in summaries[0]["runs"]] == [0, 8]


def test_budget_lists_take_ranges_for_sweep_and_compare():
    assert parse_budgets("0..3,8") == [0, 1, 2, 3, 8]
    for bad in ("0,-1", "1.5", "a..b", ""):
        with pytest.raises(ConfigError):
            parse_budgets(bad)


DCMOTOR = ROOT / "configs" / "dcmotor_shaft.yaml"
THIRD_PARTY = ROOT.parent / "shared" / "third_party" / "dcmotor"


@pytest.mark.slow  # a long sweep
@pytest.mark.skipif(not THIRD_PARTY.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_grid_and_monte_carlo_over_both_subsystems_of_the_dcmotor(tmp_path, capsys):
    """The Dymola dcmotor shaft: a grid and a Monte Carlo sweep over a parameter of each FMU (FMU
    variable names with dots: resistor.R, inertia.J). The Monte Carlo runs go without the monolithic
    reference: the machine's step map is smooth only to about 4e-7, and at some draws the interface
    Newton stops above its 1e-9 acceptance (a failed row, measured)."""
    grid = ["--set", "subsystems.machine.parameters.resistor.R=0.5,0.6",
            "--set", "subsystems.inertia.parameters.inertia.J=0.002,0.003"]
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(DCMOTOR), "--out", str(tmp_path / "grid"), "--T", "0.02", "--workers", "1", "--quiet",
              *grid])
    assert exc.value.code == 0
    rows = rows_of(tmp_path / "grid")
    assert len(rows) == 4 and all(r["status"] == "finished" for r in rows)
    assert len({r["H_final"] if "H_final" in r else r["port_energy_by_subsystem.inertia"] for r in rows}) == 4
    draws = ["--set", "subsystems.machine.parameters.resistor.R=uniform(0.4,0.6)",
             "--set", "subsystems.inertia.parameters.inertia.J=uniform(0.0015,0.0025)"]
    with pytest.raises(SystemExit) as exc:
        main(["sweep", str(DCMOTOR), "--out", str(tmp_path / "mc"), "--T", "0.02", "--workers", "1", "--quiet",
              "--sample", "3", "--seed", "5", "--no-reference", *draws])
    assert exc.value.code == 0
    rows = rows_of(tmp_path / "mc")
    assert len(rows) == 3 and all(r["status"] == "finished" for r in rows)
    assert all(0.4 <= float(r["subsystems.machine.parameters.resistor.R"]) <= 0.6 for r in rows)
