"""A run that cannot go on stops with one line naming the subsystem, the macro-step, the time and
the FMU's own message, and everything computed before is already on disk: trajectory.csv and
steps.csv hold every committed step and summary.json says why it stopped. Ctrl-C does the same.

The failures are real: DuffingSide's Newton step limited to 4 iterations first fails at
macro-step 18 from q1(0) = 2, and LinearSide with a negative spring (k2 = -1e5, not passive)
grows until its energy is no longer finite at macro-step 166."""
import copy
import csv
import json
import signal
import subprocess
import time

import pytest
import yaml

from paths import CLI, CONFIGS, THIRD_PARTY
from wavecosim.cli import main
from wavecosim.scenario.config import DEFAULT_CONFIG, parse_scenario
from wavecosim.run.runner import RunFailed, run

BASE = yaml.safe_load(DEFAULT_CONFIG.read_text())


def newton_failure(fast="auto"):
    """DuffingSide's own Newton solve limited to 4 iterations, started at q1 = 2: fails at step 18."""
    raw = copy.deepcopy(BASE)
    raw["subsystems"]["A"]["start"].update(q1=2.0, d=-2.0)
    raw["subsystems"]["A"]["integers"] = {"newton_max_iter": 4}
    raw["master"]["fast"] = fast
    return raw


def nan_failure():
    """LinearSide with a negative spring: the state grows until H is inf - inf at step 166."""
    raw = copy.deepcopy(BASE)
    raw["subsystems"]["B"]["parameters"]["k2"] = -1e5
    return raw


def rows(path):
    with open(path, newline="") as f:
        return list(csv.reader(f))[1:]


def run_cli(tmp_path, raw, capsys, *extra):
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["run", str(scenario), "--out", str(out), "--quiet", *extra])
    _, err = capsys.readouterr()
    return info.value.code, err, out


@pytest.mark.parametrize("fast", ["false", "true"], ids=["python-path", "c-kernel"])
def test_fmu_inner_solve_failure_names_subsystem_step_time(fast, tmp_path, capsys):
    code, err, out = run_cli(tmp_path, newton_failure(fast), capsys, "--no-reference")
    line = err.strip().splitlines()[-1]
    assert code == 3 and "Traceback" not in err               # FmuError: the FMU returned Error
    assert line.startswith("error: subsystem A: fmi2DoStep returned Error at step 18 (t = 0.18): ")
    assert "Newton step of the Duffing side did not converge in 4 iterations" in line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 18
    assert line == f"error: {summary['message']}"
    traj, steps = rows(out / "trajectory.csv"), rows(out / "steps.csv")
    assert len(traj) == 19 and len(steps) == 18
    assert float(traj[-1][0]) == pytest.approx(0.18) and float(steps[-1][0]) == pytest.approx(0.18)


def test_nothing_computed_is_lost(tmp_path, capsys):
    """The 18 committed steps on disk are exactly those of the same run with an unlimited Newton."""
    code, _, out = run_cli(tmp_path, newton_failure(), capsys, "--no-reference")
    assert code == 3
    raw = newton_failure()
    raw["subsystems"]["A"]["integers"] = {"newton_max_iter": 50}
    raw["T"] = 0.2
    full = run(parse_scenario(raw, "full", DEFAULT_CONFIG.parent), certificates=False)
    on_disk = rows(out / "trajectory.csv")
    for k, row in enumerate(on_disk):
        assert [float(x) for x in row[1:]] == pytest.approx(list(full.outputs[k]), rel=0, abs=0)


def test_failing_reference_keeps_its_rows(tmp_path, capsys):
    """Without --no-reference the monolithic reference runs first and meets the same failure."""
    code, err, out = run_cli(tmp_path, newton_failure(), capsys)
    assert code == 3
    assert err.strip().splitlines()[-1].startswith("error: subsystem A: fmi2DoStep returned Error at step 18 (t = 0.18)")
    assert len(rows(out / "trajectory_monolithic.csv")) == 19
    assert json.loads((out / "summary_monolithic.json").read_text())["status"] == "failed"


@pytest.mark.parametrize("fast", ["false", "true"], ids=["python-path", "c-kernel"])
def test_growth_past_the_bound_stops_the_run_with_the_rows_computed(fast, tmp_path, capsys):
    """The negative spring's v2 passes growth_bound (1e12) times the outputs' initial scale (1) at
    step 14: NumericalError (exit 4) naming subsystem, variable and step; the rows up to that step
    are on disk, the same from the step-by-step route and the kernel's blocks."""
    raw = nan_failure()
    raw["master"]["fast"] = fast
    code, err, out = run_cli(tmp_path, raw, capsys, "--no-reference")
    assert code == 4
    assert err.strip().splitlines()[-1] == ("error: subsystem B: v2 = 3.44937e+12 at step 14 (t = 0.15) has grown "
                                            "past 1e+12 (growth_bound 1e+12 times the outputs' initial scale 1)")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 15
    assert len(rows(out / "trajectory.csv")) == 16 and len(rows(out / "steps.csv")) == 15
    with open(out / "trajectory.csv", newline="") as f:
        table = list(csv.reader(f))
    v2 = [abs(float(row[table[0].index("v2")])) for row in table[1:]]
    assert v2[-1] > 1e12 > max(v2[:-1])


def test_non_finite_state_stops_the_run(tmp_path, capsys):
    """Without a growth bound (growth_bound: null) the state grows until the FMU itself refuses."""
    raw = nan_failure()
    raw["growth_bound"] = None
    code, err, out = run_cli(tmp_path, raw, capsys, "--no-reference")
    line = err.strip().splitlines()[-1]
    assert code == 3
    assert line.startswith("error: subsystem B: fmi2DoStep returned Error at step 166 (t = 1.66): ")
    assert line.endswith("H is not finite after the step")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and summary["steps"] == 166
    assert len(rows(out / "trajectory.csv")) == 167 and len(rows(out / "steps.csv")) == 166
    # the last committed values are finite and large: the blow-up is on disk up to the failing step
    last = [abs(float(x)) for x in rows(out / "trajectory.csv")[-1][1:]]
    assert all(x < float("inf") for x in last) and max(last) > 1e100


def test_an_fmu_that_overflows_without_an_error_stops_the_kernel_block(tmp_path, capsys):
    """The Reference FMUs' Dahlquist (x' = -k x, forward Euler) with k = -1e300 reaches x = inf at step 1
    and says nothing: without a growth bound the kernel's block stops after that step on its own
    finiteness check, and the run fails there with the rows before it."""
    fmu = THIRD_PARTY / "reference_fmus" / "fmi2" / "Dahlquist.fmu"
    if not fmu.exists():
        pytest.skip("the Reference FMUs are not beside this clone")
    raw = {"name": "dahlquist_overflow", "dt": 0.1, "T": 1.0, "growth_bound": None,
           "subsystems": {"D": {"fmu": str(fmu), "parameters": {"k": -1e300}}}, "outputs": {"x": "D.x"}}
    code, err, out = run_cli(tmp_path, raw, capsys)
    assert code == 4 and err.strip().splitlines()[-1] == "error: subsystem D: x = inf is not finite at step 1 (t = 0.2)"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fast_path"] and summary["block_steps"] == 2 and summary["steps"] == 2
    assert [r[1] for r in rows(out / "trajectory.csv")] == ["1.0", "1e+299", "inf"]


def test_run_failed_carries_the_result():
    """The library API: RunFailed.result holds the committed rows, the step and the message."""
    with pytest.raises(RunFailed) as info:
        run(parse_scenario(newton_failure(), "newton", DEFAULT_CONFIG.parent), certificates=False)
    result = info.value.result
    assert result.status == "failed" and len(result.t) == 19 and result.t[-1] == pytest.approx(0.18)
    assert "at step 18 (t = 0.18)" in str(info.value)


def test_ctrl_c_stops_cleanly_with_everything_on_disk(tmp_path):
    """SIGINT during a long run: exit 130, one line, and the CSV files and summary agree on the
    number of committed steps (status 'interrupted')."""
    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "run", "--T", "10000", "--out", str(out), "--quiet", "--no-reference",
                             "--no-certificates"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    steps_csv = out / "steps.csv"
    deadline = time.time() + 120
    while time.time() < deadline:
        if steps_csv.exists() and len(steps_csv.read_text().splitlines()) > 500:
            break
        time.sleep(0.05)
    else:
        proc.kill()
        pytest.fail("the run never wrote its first rows")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("interrupted: interrupted by the user after ")
    assert lines[0].endswith("steps; results so far are on disk")
    summary = json.loads((out / "summary.json").read_text())
    n = summary["steps"]
    assert summary["status"] == "interrupted" and 500 <= n < 1_000_000
    assert f"after {n} steps" in lines[0]
    traj, steps = rows(out / "trajectory.csv"), rows(out / "steps.csv")
    assert len(steps) == n and len(traj) == n + 1
    assert float(traj[-1][0]) == pytest.approx(n * 0.01) and all(len(r) == len(traj[0]) for r in traj)


def test_explicit_master_on_an_unstable_stiff_scene_fails_instead_of_finishing(tmp_path, capsys):
    """configs/two_oscillators_stiff.yaml with m1 = -8 under the explicit master grows without bound
    (q1 = 2.4e25 by the end): the run stops where its outputs pass the growth bound."""
    raw = yaml.safe_load((CONFIGS / "two_oscillators_stiff.yaml").read_text())
    raw["subsystems"]["A"]["parameters"]["m1"] = -8.0
    code, err, out = run_cli(tmp_path, raw, capsys, "--no-reference", "--master", "explicit")
    summary = json.loads((out / "summary.json").read_text())
    assert code == 4 and summary["status"] == "failed" and summary["steps"] < raw["T"] / raw["dt"]
    assert err.strip().splitlines()[-1] == ("error: subsystem A: b = 1.18557e+12 at step 117 (t = 1.18) has grown "
                                            "past 1e+12 (growth_bound 1e+12 times the outputs' initial scale 1)")
    assert len(rows(out / "trajectory.csv")) == summary["steps"] + 1


def test_a_non_finite_value_at_t0_is_one_line(tmp_path, capsys):
    """An FMU whose stored energy is infinite at t = 0 (StrictMass with m = 1e308, v = 1e10), with a
    fixed gamma: one line naming subsystem and variable (exit 4), the first row kept, a summary."""
    raw = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
    raw["gamma"] = 0.5
    raw["subsystems"]["A"].update(fmu="StrictMass", parameters={"m": 1e308}, start={"v": 1e10})
    code, err, out = run_cli(tmp_path, raw, capsys, "--no-reference")
    assert code == 4
    assert err.strip().splitlines()[-1] == ("error: subsystem A: its stored energy H = inf is not finite at t = 0 "
                                            "(the initial values)")
    assert json.loads((out / "summary.json").read_text())["status"] == "failed"
    assert len(rows(out / "trajectory.csv")) == 1
