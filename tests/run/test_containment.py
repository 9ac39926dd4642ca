"""A run whose FMU segfaults, calls exit(0), aborts or never returns inside doStep at step 2500 of 3000
(the FaultySide test FMU, models/faulty_side) keeps every step before it: one line naming the
subsystem and the call, an exit code of its own, 2500 rows in trajectory.csv equal to those of the
same run without the fault, summary.json saying what happened, and nothing left in the temporary
folder. SIGTERM stops a run as Ctrl-C does, also inside a call that does not return."""
import json
import os
import signal
import subprocess
import time

import pytest
import yaml

from paths import CLI

FAULTS = {"segfault": (1, 5, "{who}: the FMU crashed (SIGSEGV: segmentation fault) in fmi2DoStep at step 2500 (t = 25)"),
          "exit": (2, 5, "{who}: the FMU ended the process with exit(0) in fmi2DoStep at step 2500 (t = 25)"),
          "hang": (3, 6, "step 2500 (t = 25) did not finish within 2 s (step timeout); stopped inside {who} in "
                         "fmi2DoStep"),
          "abort": (4, 5, "{who}: the FMU crashed (SIGABRT: aborted) in fmi2DoStep at step 2500 (t = 25)")}


def lines(path):
    return path.read_bytes().split(b"\r\n")[1:-1]


@pytest.fixture
def tmp_env(tmp_path):
    """An environment whose temporary folder is this test's own (to see what a run leaves there)."""
    temp = tmp_path / "temp"
    temp.mkdir()
    return {**os.environ, "TMPDIR": str(temp)}, temp


def wavecosim(tmp_path, env, raw, *options, timeout=120):
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    proc = subprocess.run([*CLI, "run", str(scenario), "--out", str(out), "--quiet", *options], env=env,
                          capture_output=True, text=True, timeout=timeout)
    return proc, out


@pytest.fixture(scope="module")
def fault_free(tmp_path_factory, faulty_scenario):
    """The same run without a fault (its first rows are what a faulted run must keep)."""
    proc, out = wavecosim(tmp_path_factory.mktemp("fault_free"), os.environ, faulty_scenario(), "--step-timeout", "5")
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("name", [name if name in ("segfault", "hang") else pytest.param(name, marks=pytest.mark.slow)
                                  for name in FAULTS])
def test_a_fault_in_dostep_keeps_every_step_before_it(name, tmp_path, tmp_env, fault_free, faulty_scenario):
    fault, code, what = FAULTS[name]
    env, temp = tmp_env
    proc, out = wavecosim(tmp_path, env, faulty_scenario(fault, 2500), "--step-timeout", "2")
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == code and len(err) == 1, proc.stderr
    # the reference runs ahead and meets the fault first; the run is brought up to the same step
    assert err[0] == "error: " + what.format(who="subsystem B (monolithic reference)")
    for suffix in ("", "_monolithic"):
        summary = json.loads((out / f"summary{suffix}.json").read_text())
        assert summary["status"] == ("timed out" if name == "hang" else "crashed")
        assert summary["steps"] == 2500 and f"error: {summary['message']}" == err[0]
        assert lines(out / f"trajectory{suffix}.csv") == lines(fault_free / f"trajectory{suffix}.csv")[:2501]
        assert lines(out / f"steps{suffix}.csv") == lines(fault_free / f"steps{suffix}.csv")[:2500]
    assert list(temp.iterdir()) == []                 # no extracted FMU, no channel folder


@pytest.fixture(scope="module")
def fault_free_alone(tmp_path_factory, faulty_scenario):
    """The same run without a fault and without the reference."""
    proc, out = wavecosim(tmp_path_factory.mktemp("fault_free_alone"), os.environ, faulty_scenario(), "--no-reference")
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.mark.parametrize("name", ["segfault", pytest.param("hang", marks=pytest.mark.slow)])
def test_without_the_reference_the_kernel_block_in_progress_is_kept(name, tmp_path, tmp_env, faulty_scenario,
                                                                     fault_free_alone):
    """The C kernel makes the steps in blocks, and the rows' and Condition 2's passes as it logs them;
    the rescue books the block's steps before the fault, making the passes over those the kernel had
    not gone over yet (the fault is hundreds of steps into a block)."""
    fault, code, what = FAULTS[name]
    proc, out = wavecosim(tmp_path, tmp_env[0], faulty_scenario(fault, 2500), "--no-reference", "--step-timeout", "2")
    assert proc.returncode == code
    assert proc.stderr.strip() == "error: " + what.format(who="subsystem B")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 2500 and 0 < summary["block_steps"] <= 2500          # blocks of the C kernel ran
    assert lines(out / "trajectory.csv") == lines(fault_free_alone / "trajectory.csv")[:2501]
    assert lines(out / "steps.csv") == lines(fault_free_alone / "steps.csv")[:2500]


def test_a_process_killed_outright_still_gets_its_summary(tmp_path, tmp_env, faulty_scenario):
    """SIGKILL of the child (as the out-of-memory killer does): the parent writes every row committed
    (the rows on disk, cut after the last whole one, and those in the tables' shared memory) and
    summary.json: the reference, which runs ahead, made the 2900 steps before its hang."""
    env, temp = tmp_env
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(faulty_scenario(3, 2900), sort_keys=False))
    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "run", str(scenario), "--out", str(out), "--quiet"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    child = _child_when_hung(proc.pid, out / "trajectory.csv")
    time.sleep(1.5)                                   # the rows booked reach the file at least every second
    os.kill(child, signal.SIGKILL)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 5 and err.startswith("error: the run crashed (SIGKILL)"), err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "crashed" and summary["fault"]["signal"] == "SIGKILL"
    rows = lines(out / "trajectory.csv")
    assert summary["steps"] == len(rows) - 1 >= 1024 and all(r.count(b",") == rows[0].count(b",") for r in rows)
    assert summary["message"] == (f"the run crashed (SIGKILL) inside subsystem B (monolithic reference) in fmi2DoStep; "
                                  f"{summary['steps']} steps kept")        # the call in progress, from the status page
    reference = json.loads((out / "summary_monolithic.json").read_text())
    assert reference["steps"] == len(lines(out / "trajectory_monolithic.csv")) - 1 == 2900
    assert list(temp.iterdir()) == []


def _child_when_hung(parent, trajectory, timeout=60):
    """The pid of the parent's child once its run has written more than a block of rows (it then
    hangs in the reference's step 2900, after at least 1876 rows: the blocks are at most 1024 steps)."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        children = open(f"/proc/{parent}/task/{parent}/children").read().split()
        if children and trajectory.exists() and trajectory.read_bytes().count(b"\n") > 1025:
            return int(children[0])
        time.sleep(0.1)
    for pid in [*open(f"/proc/{parent}/task/{parent}/children").read().split(), parent]:
        os.kill(int(pid), signal.SIGKILL)                # nothing left spinning after the failure
    pytest.fail("the run never wrote a block of rows")


@pytest.mark.parametrize("hung", [False, pytest.param(True, marks=pytest.mark.slow)], ids=["between-steps", "inside-a-hung-call"])
def test_sigterm_ends_the_run_cleanly(hung, tmp_path, tmp_env, faulty_scenario):
    """SIGTERM: exit 143, one line, every committed step on disk and in summary.json (status
    interrupted), also when the run is stuck in an FMU call (the parent asks for a rescue)."""
    env, temp = tmp_env
    raw = faulty_scenario(3 if hung else 0, 600, T=10000.0)
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "run", str(scenario), "--out", str(out), "--quiet", "--no-reference",
                             "--no-certificates"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline, enough = time.time() + 60, 0 if hung else 550       # a hang at 600 holds its block's rows
    while not ((out / "steps.csv").exists() and len((out / "steps.csv").read_bytes().split(b"\n")) > enough):
        assert time.time() < deadline and proc.poll() is None, "the run never wrote its first rows"
        time.sleep(0.05)
    time.sleep(3.0 if hung else 0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    lines_err = err.strip().splitlines()
    assert len(lines_err) == 1 and lines_err[0].startswith("interrupted: stopped by SIGTERM") and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    n = summary["steps"]
    assert summary["status"] == "interrupted" and (n == 600 if hung else n > 550)
    if hung:                                       # stopped where it hung (after the parent's grace)
        assert "inside subsystem B in fmi2DoStep" in summary["message"]
    else:                                          # the child itself stopped between two steps
        assert summary["message"] == f"stopped by SIGTERM after {n} steps"
    assert len(lines(out / "trajectory.csv")) == n + 1 and len(lines(out / "steps.csv")) == n
    assert list(temp.iterdir()) == []


def test_rows_reach_the_file_at_least_every_second(tmp_path, faulty_scenario):
    """Step by step (no kernel blocks) the rows fill blocks of 1024 in memory; a second after the last
    hand-over the rows booked so far are handed to the writer anyway, so a death loses at most about
    a second of steps."""
    from wavecosim.run.runner import run
    from wavecosim.scenario.config import parse_scenario
    raw = faulty_scenario(T=5.0)
    raw["master"]["fast"] = False
    seen = {}

    def progress(n, total):
        if n >= 100 and "slept" not in seen:
            seen["slept"] = n
            time.sleep(1.2)                              # a slow step: the next one hands the rows over
        elif n >= 300 and "rows" not in seen:
            deadline = time.time() + 5
            while time.time() < deadline and len(lines(tmp_path / "trajectory.csv")) <= seen["slept"]:
                time.sleep(0.05)
            seen["rows"] = len(lines(tmp_path / "trajectory.csv"))
    run(parse_scenario(raw, "faulty", tmp_path), tmp_path, certificates=False, progress=progress, file_suffix=False)
    assert seen["slept"] < seen["rows"] < 1024


def test_the_call_in_progress_names_only_what_it_knows():
    """The status page's call in progress fills in a fault no stack named: its component's subsystem
    during the runs, the subsystem whose FMU the set-up opens before them, the call alone for an
    instance no run knows (a shim's), and nothing between calls; a stack that named one is kept."""
    from wavecosim.run.channel import in_progress
    runs = {0x1000: "B (monolithic reference)"}
    assert in_progress(("", ""), (0x1000, "fmi2DoStep", "A"), runs) == ("subsystem B (monolithic reference)",
                                                                       "fmi2DoStep")
    assert in_progress(("an FMU (X.so)", "fmi2Instantiate"), (0, "fmi2Instantiate", "B~probe"), {}) == \
        ("subsystem B", "fmi2Instantiate")
    assert in_progress(("", ""), (0x2000, "fmi2DoStep", "A"), runs) == ("", "fmi2DoStep")
    assert in_progress(("", ""), (0x1000, "", "A"), runs) == ("", "")
    assert in_progress(("subsystem A", "fmi2DoStep"), (0x1000, "fmi2GetReal", "A"), runs) == ("subsystem A", "fmi2DoStep")
