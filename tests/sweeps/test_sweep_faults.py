"""A sweep whose runs crash or hang: each such run is one row with its status and message, the others
are kept, --resume runs only the failed one (once more), the sweep exits 8, and SIGTERM leaves no
process behind."""
import json
import os
import signal
import subprocess
import time

import pytest
import yaml

from paths import CLI


@pytest.fixture
def scenario(tmp_path, faulty_scenario):
    """scenario(fault, **top): a file of Table I with B a FaultySide with that fault (the sweep sets
    its fault_step), T = 0.5."""
    def write(fault, **top):
        raw = faulty_scenario(fault, -1, T=0.5)
        raw.update(top)
        path = tmp_path / "faulty.yaml"
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
        return path
    return write


def sweep(path, out, *extra, env=None):
    return subprocess.run([*CLI, "sweep", str(path), "--set", "subsystems.B.integers.fault_step=-1,-2,20,-3",
                           "--workers", "2", "--out", str(out), "--quiet", "--no-certificates", *extra],
                          capture_output=True, text=True, timeout=300, env=env)


def rows(out):
    return json.loads((out / "runs.json").read_text())["runs"]


def test_a_crashing_run_is_one_row_and_the_others_are_kept(tmp_path, scenario):
    out = tmp_path / "out"
    proc = sweep(scenario(1), out)
    assert proc.returncode == 8, proc.stderr
    assert proc.stderr.strip() == f"error: 1 of 4 runs did not finish (their rows say why: {out / 'runs.csv'})"
    got = rows(out)
    assert [r["status"] for r in got] == ["finished", "finished", "crashed", "finished"]
    assert all(r["steps"] == 50 for r in got if r["status"] == "finished")
    crashed = got[2]
    assert crashed["steps"] == 20 and crashed["message"] == (
        "subsystem B (monolithic reference): the FMU crashed (SIGSEGV: segmentation fault) in fmi2DoStep "
        "at step 20 (t = 0.2)")
    assert "run 2 (2_fault_step-20): crashed: subsystem B" in proc.stdout
    # --resume: the three finished runs are kept as they are, the crashed one is tried once more
    kept = {r["index"]: r["task_time_s"] for r in got}
    again = sweep(scenario(1), out, "--resume")
    assert again.returncode == 8
    second = rows(out)
    assert [r["task_time_s"] == kept[r["index"]] for r in second] == [True, True, False, True]
    assert second[2]["attempts"] == 2 and second[2]["status"] == "crashed"
    third = sweep(scenario(1), out, "--resume")
    assert third.returncode == 8 and rows(out) == second             # failed twice: kept, not tried again


@pytest.mark.slow
def test_a_hanging_run_times_out_and_the_sweep_ends(tmp_path, scenario):
    out = tmp_path / "out"
    proc = sweep(scenario(3, step_timeout=2.0), out)
    assert proc.returncode == 8
    got = rows(out)
    assert [r["status"] for r in got] == ["finished", "finished", "timed out", "finished"]
    assert got[2]["message"] == ("step 20 (t = 0.2) did not finish within 2 s (step timeout); stopped inside "
                                 "subsystem B (monolithic reference) in fmi2DoStep")


@pytest.mark.slow
def test_sigterm_stops_the_sweep_and_leaves_no_process(tmp_path, scenario):
    out = tmp_path / "out"
    env = {**os.environ}
    proc = subprocess.Popen([*CLI, "sweep", str(scenario(3)), "--set",
                             "subsystems.B.integers.fault_step=20,21,22,23", "--workers", "2", "--out", str(out),
                             "--quiet", "--no-certificates"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)
    deadline, children = time.time() + 60, []
    while len(children) < 2 or len(list(out.glob("runs/*/trajectory.csv"))) < 2:    # both runs stepping
        assert time.time() < deadline and proc.poll() is None
        children = open(f"/proc/{proc.pid}/task/{proc.pid}/children").read().split()
        time.sleep(0.2)
    time.sleep(1.0)                                                # and hung at steps 20 and 21
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1].startswith("interrupted: sweep stopped after 2 of 4 runs")
    for pid in children:
        assert not os.path.exists(f"/proc/{pid}"), f"process {pid} is still there"
    got = rows(out)
    assert [r["status"] for r in got] == ["interrupted", "interrupted"]
    assert all("inside subsystem B" in r["message"] and "in fmi2DoStep" in r["message"] for r in got)
