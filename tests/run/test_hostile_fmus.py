"""Faults that escape a plain rescue, contained all the same (the FaultySide test FMU's hostile modes,
models/faulty_side): a hang whose FMU blocks or handles the freeze signal, a process that stops
itself, a helper the FMU forked, hangs in the set-up (instantiate, the probes' restore, the library's
load), a crash in a thread the FMU started, NaN at initialization, a binary that does not load, a
chdir mid-run and a parent killed outright. Each: its exit code, one line, the rows kept (as many
as the summary says) and nothing left in the temporary folder nor running."""
import json
import os
import re
import signal
import subprocess
import time
import zipfile

import pytest
import yaml

from paths import CLI

STEP = 50                         # the fault's macro-step (T = 1, dt = 0.01: 100 steps)


@pytest.fixture
def hostile(tmp_path, faulty_scenario):
    """hostile(fault, *options, env=None, fmu=None) -> (process, out folder, temp folder): a run of
    the FaultySide scene faulting at STEP, in tmp_path (a relative --out), with a temporary folder
    of its own; the run's own processes are gone when it returns."""
    def run(fault, *options, env=None, fmu=None):
        raw = faulty_scenario(fault, STEP, T=1.0)
        if fmu is not None:
            raw["subsystems"]["B"]["fmu"] = str(fmu)
        (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
        temp = tmp_path / "temp"
        temp.mkdir(exist_ok=True)
        proc = subprocess.run([*CLI, "run", "scenario.yaml", "--out", "out", "--quiet", "--step-timeout", "1",
                               "--setup-timeout", "2", *options], cwd=tmp_path, capture_output=True, text=True,
                              env={**os.environ, "TMPDIR": str(temp), **(env or {})}, timeout=60)
        assert _running_in(tmp_path) == []
        return proc, tmp_path / "out", temp
    return run


def _running_in(folder):
    """The processes whose working directory is `folder` (a run's, a helper it forked)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            if os.readlink(f"/proc/{pid}/cwd") == str(folder):
                found.append(int(pid))
        except OSError:
            pass
    return found


def _rows(path):
    """The rows of a CSV file below its header (0 when it is empty or missing)."""
    return max(path.read_bytes().count(b"\n") - 1, 0) if path.exists() else 0


def _one_line(proc, code):
    lines = [ln for ln in proc.stderr.strip().splitlines() if not ln.startswith("wavecosim: building")]
    assert proc.returncode == code and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


def _kept(out, steps=None):
    """The steps the summary says are kept, checked against the rows on disk (and `steps`, if given)."""
    summary = json.loads((out / "summary.json").read_text())
    assert _rows(out / "steps.csv") == summary["steps"] == max(_rows(out / "trajectory.csv") - 1, 0)
    assert steps is None or summary["steps"] == steps
    return summary


@pytest.mark.slow
@pytest.mark.parametrize("fault,options,step", [(5, (), STEP), (7, (), STEP), (5, ("--set", "master.fast=false"), STEP),
                                                (5, ("--set", "subsystems.B.substeps=2"), STEP // 2)],
                         ids=["signals-blocked", "own-handlers", "python-route", "substeps"])
def test_a_hang_that_holds_the_freeze_signal_is_rescued(fault, options, step, hostile):
    """The watchdog takes the freeze the FMU never takes; the rescue writes every step before it, and
    names the subsystem and the call from the call in progress the kernel (or the Python route, or the
    kernel's multi-rate shim) records in the status page (no stack is taken). The FMU faults at its
    STEP-th doStep: with two substeps a macro-step makes two."""
    proc, out, temp = hostile(fault, "--no-reference", *options)
    line = _one_line(proc, 6)
    assert line == (f"error: step {step} (t = {step / 100:g}) did not finish within 1 s (step timeout); stopped "
                    "inside subsystem B in fmi2DoStep; the FMU holds the signal that would stop it")
    assert _kept(out, step)["status"] == "timed out" and list(temp.iterdir()) == []


@pytest.mark.slow
def test_a_process_that_stops_itself_is_ended(hostile):
    """SIGSTOP: the parent sees it stopped, waits the step timeout and ends its process group."""
    proc, out, temp = hostile(6, "--no-reference")
    line = _one_line(proc, 6)
    assert line.startswith("error: a step did not finish within 1 s (step timeout); it stopped itself (SIGSTOP) "
                           "inside subsystem B in fmi2DoStep")
    summary = _kept(out, STEP)                      # the kernel call in progress too: its rows were counted
    assert summary["status"] == "timed out" and list(temp.iterdir()) == []


@pytest.mark.slow
def test_a_helper_the_fmu_forked_neither_holds_the_run_nor_outlives_it(hostile):
    started = time.monotonic()
    proc, out, temp = hostile(9, "--no-reference")
    line = _one_line(proc, 5)
    assert line == f"error: subsystem B: the FMU crashed (SIGSEGV: segmentation fault) in fmi2DoStep at step {STEP} (t = 0.5)"
    assert time.monotonic() - started < 30 and _kept(out, STEP) and list(temp.iterdir()) == []


def test_a_crash_in_a_thread_the_fmu_started(hostile):
    proc, out, temp = hostile(8, "--no-reference")
    line = _one_line(proc, 5)
    assert line == (f"error: subsystem B: the FMU crashed (SIGSEGV: segmentation fault) in a thread it started "
                    f"at step {STEP} (t = 0.5)")
    assert _kept(out, STEP)["status"] == "crashed" and list(temp.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("where,fault,env,call", [
    ("instantiate", 0, {"FAULTYSIDE_HANG": "instantiate"}, "fmi2Instantiate"),
    ("restore", 13, {}, "fmi2SetFMUstate")])
def test_a_hang_in_the_set_up_ends_at_the_set_up_timeout(where, fault, env, call, hostile):
    started = time.monotonic()
    proc, out, temp = hostile(fault, "--step-timeout", "30", env=env)          # the set-up's own timeout ends it
    assert time.monotonic() - started < 20
    line = _one_line(proc, 6)
    assert line == f"error: the set-up did not finish within 2 s (set-up timeout); stopped inside subsystem B in {call}"
    assert _rows(out / "steps.csv") == 0 and list(temp.iterdir()) == []


@pytest.mark.slow
def test_a_hang_while_the_library_loads_ends_too(hostile):
    """dlopen holds the interpreter: the child's watchdog cannot run, and the parent ends the child."""
    proc, out, temp = hostile(0, env={"FAULTYSIDE_HANG": "load"})
    line = _one_line(proc, 6)
    assert line.startswith("error: the set-up did not finish within 2 s (set-up timeout); it went silent (stuck "
                           "holding the interpreter) inside subsystem B in the load of its binary")
    assert list(temp.iterdir()) == []


def test_nan_at_initialization_is_a_numerical_error(hostile):
    proc, out, temp = hostile(14)
    line = _one_line(proc, 4)
    assert line == "error: subsystem B: b = nan is not finite at t = 0 (the initial values)"
    assert list(temp.iterdir()) == []


def test_a_binary_that_does_not_load_is_an_fmu_error(hostile, tmp_path):
    from wavecosim.fmi.builtin import builtin_fmus
    broken = tmp_path / "Broken.fmu"
    with zipfile.ZipFile(builtin_fmus()["FaultySide"]) as zin, zipfile.ZipFile(broken, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, b"not a shared library\n" * 100 if item.filename.endswith(".so") else zin.read(item))
    proc, out, temp = hostile(0, fmu=broken)
    line = _one_line(proc, 3)
    assert line == "error: subsystem B: its binary FaultySide.so does not load (invalid ELF header)"
    assert list(temp.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("master", ["dr", pytest.param("jacobi-iter", marks=pytest.mark.slow)])
def test_a_restore_that_drifts_during_the_run_stops_it(master, hostile):
    """The probes at set-up find the restore exact; from step 50 on it multiplies v by 1 + 1e-4. The
    re-check after the steps catches it: exit 3, the steps made so far kept."""
    proc, out, temp = hostile(12, "--no-reference", "--no-certificates", "--master", master)
    line = _one_line(proc, 3)
    assert re.fullmatch(r"error: subsystem B: its restore no longer reproduces its state: fmi2SetFMUstate after "
                        r"step (\d+) changed its outputs by [0-9.e+-]+ \(relative\); a master that rolls back would "
                        r"give wrong results", line), line
    steps = int(re.search(r"after step (\d+)", line).group(1))
    assert STEP < steps <= 100 and _kept(out, steps)["status"] == "failed" and list(temp.iterdir()) == []


def test_a_chdir_mid_run_writes_every_file_into_the_folder_named(hostile, tmp_path):
    proc, out, temp = hostile(11, "--no-reference")
    assert proc.returncode == 0, proc.stderr
    assert {"trajectory.csv", "steps.csv", "summary.json", "metadata.json"} <= {p.name for p in out.iterdir()}
    assert _kept(out, 100)["status"] == "finished"


@pytest.mark.slow
def test_a_parent_killed_outright_leaves_nothing_behind(tmp_path, faulty_scenario):
    """SIGKILL of the parent while its child hangs in doStep (no step timeout): the child gets SIGTERM,
    the janitor ends it and removes the channel folder."""
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(faulty_scenario(5, STEP, T=1.0), sort_keys=False))
    temp = tmp_path / "temp"
    temp.mkdir()
    proc = subprocess.Popen([*CLI, "run", "scenario.yaml", "--out", "out", "--quiet", "--no-reference"], cwd=tmp_path,
                            env={**os.environ, "TMPDIR": str(temp)}, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and len(_running_in(tmp_path)) < 2:
        time.sleep(0.1)
    time.sleep(1.0)                                     # the child is inside the hung doStep
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and (_running_in(tmp_path) or list(temp.iterdir())):
        time.sleep(0.2)
    left = _running_in(tmp_path)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert left == [] and list(temp.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_stop_while_the_fmu_holds_every_signal_keeps_every_step(signum, tmp_path, faulty_scenario):
    """Ctrl-C (to the process group) or SIGTERM while doStep hangs with every signal blocked, no step
    timeout: the run's watchdog takes the stop the FMU never lets through, and the rescue writes every
    step before the hung one, naming the call, as a stop between two steps would."""
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(faulty_scenario(5, STEP, T=1.0), sort_keys=False))
    temp = tmp_path / "temp"
    temp.mkdir()
    proc = subprocess.Popen([*CLI, "run", "scenario.yaml", "--out", "out", "--quiet", "--no-reference"], cwd=tmp_path,
                            env={**os.environ, "TMPDIR": str(temp)}, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    deadline = time.monotonic() + 30
    while not (tmp_path / "out" / "steps.csv").exists():                # stepping
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.1)
    time.sleep(1.5)                                                     # and inside the hung doStep
    os.killpg(proc.pid, signum) if signum == signal.SIGINT else proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    verb = "interrupted by the user" if signum == signal.SIGINT else "stopped by SIGTERM"
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("wavecosim: building")]
    assert proc.returncode == 128 + signum and lines == [
        f"interrupted: {verb} at step {STEP} (t = 0.5), inside subsystem B in fmi2DoStep; results so far are on disk"]
    assert _kept(tmp_path / "out", STEP)["status"] == "interrupted" and list(temp.iterdir()) == []
    assert _running_in(tmp_path) == []
