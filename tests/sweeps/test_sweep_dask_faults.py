"""A sweep on a Dask LocalCluster whose runs crash or hang: each Dask task runs its run in a supervised
child of the worker, so a segfault, an endless loop or a signal-blind hang is one row with its status
(no KilledWorker, no retry), --step-timeout ends a hung run, the good runs are complete, and neither a
process nor a temporary folder of the sweep is left."""
import json
import os
import signal
import subprocess
import time

import pytest
import yaml

from paths import CLI

FAULTS = "0,1,3,5"          # none, segfault, endless loop, endless loop with every signal blocked


def sweep(tmp_path, faulty_scenario, scheduler="local"):
    """(process, seconds, out, temp): the sweep of FAULTS at step 20 with --step-timeout 2 on the
    scheduler (2 workers of a LocalCluster by default), its temporary files in tmp_path/tmp."""
    path, out, temp = tmp_path / "faulty.yaml", tmp_path / "out", tmp_path / "tmp"
    path.write_text(yaml.safe_dump(faulty_scenario(0, 20, T=0.5), sort_keys=False))
    temp.mkdir(exist_ok=True)
    started = time.monotonic()
    proc = subprocess.run([*CLI, "sweep", str(path), "--set", f"subsystems.B.integers.fault={FAULTS}",
                           "--scheduler", scheduler, "--workers", "2", "--out", str(out), "--quiet",
                           "--no-certificates", "--step-timeout", "2"], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "TMPDIR": str(temp)})
    return proc, time.monotonic() - started, out, temp


def survivors(temp):
    """The processes whose environment names the sweep's temporary folder (all it started inherit it)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            environ = open(f"/proc/{pid}/environ", "rb").read()
        except OSError:
            continue
        if f"TMPDIR={temp}".encode() in environ.split(b"\0"):
            found.append(pid)
    return found


def check_rows(proc, seconds, out):
    """Exit 8 in time; one row per run with its status, summary.json and every row made before the fault."""
    assert proc.returncode == 8, proc.stderr
    assert proc.stderr.strip() == f"error: 3 of 4 runs did not finish (their rows say why: {out / 'runs.csv'})"
    assert seconds < 60, seconds                     # the hangs ended by the timeout, not by the test's
    runs = json.loads((out / "runs.json").read_text())["runs"]
    assert [r["status"] for r in runs] == ["finished", "crashed", "timed out", "timed out"]
    assert all(r.get("attempts") == 1 for r in runs)
    assert runs[0]["steps"] == 50
    assert runs[1]["message"].startswith("subsystem B (monolithic reference): the FMU crashed (SIGSEGV")
    assert runs[2]["message"].startswith("step 20 (t = 0.2) did not finish within 2 s (step timeout)")
    assert "did not finish within 2 s (step timeout)" in runs[3]["message"]
    for run in runs:
        folder = next((out / "runs").glob(f"{run['index']}_*"))
        summary = json.loads((folder / "summary.json").read_text())
        assert summary["status"] == run["status"]
        lines = (folder / "trajectory.csv").read_text().splitlines()
        assert len(lines) - 1 == (51 if run["status"] == "finished" else 21), (run["status"], len(lines))


@pytest.mark.slow  # starts a Dask LocalCluster; two runs hang until their step timeout
def test_faulty_runs_on_a_local_cluster_are_rows_and_nothing_is_left(tmp_path, faulty_scenario):
    proc, seconds, out, temp = sweep(tmp_path, faulty_scenario)
    check_rows(proc, seconds, out)
    time.sleep(1.0)                                  # janitors finish within a second of their run
    assert survivors(temp) == []
    assert list(temp.iterdir()) == []


@pytest.mark.slow  # starts a Dask LocalCluster; two runs hang until their step timeout
def test_the_workers_of_a_scheduler_survive_faulty_runs(tmp_path, faulty_scenario):
    from distributed import Client, LocalCluster
    temp = tmp_path / "tmp"
    temp.mkdir()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      local_directory=str(tmp_path / "dask"), env={"TMPDIR": str(temp)}) as cluster, \
            Client(cluster) as client:
        workers = set(client.scheduler_info()["workers"])
        proc, seconds, out, _ = sweep(tmp_path, faulty_scenario, cluster.scheduler_address)
        check_rows(proc, seconds, out)
        assert set(client.scheduler_info()["workers"]) == workers          # none died, none replaced
        time.sleep(1.0)
        assert sorted(p.name for p in temp.iterdir()) == []                # no run's folder left


@pytest.mark.slow  # starts a Dask LocalCluster; its runs hang until they are stopped
@pytest.mark.parametrize("signum,group", [(signal.SIGINT, True), (signal.SIGTERM, False), (signal.SIGTERM, True)],
                         ids=["ctrl-c", "sigterm", "sigterm-to-the-group"])
def test_a_stopped_sweep_on_a_local_cluster_keeps_the_rows_of_its_runs(signum, group, tmp_path, faulty_scenario):
    """Ctrl-C (SIGINT to the whole process group, the workers included) or SIGTERM (to the command or to
    its group) while two runs hang in doStep (no step timeout): each stops where it is, with its rows
    and a summary that says interrupted and names the call; the third run never starts; nothing is left."""
    path, out, temp = tmp_path / "faulty.yaml", tmp_path / "out", tmp_path / "tmp"
    path.write_text(yaml.safe_dump(faulty_scenario(3, 20, T=0.5), sort_keys=False))
    temp.mkdir()
    proc = subprocess.Popen([*CLI, "sweep", str(path), "--set", "subsystems.B.integers.fault_step=20,21,22",
                             "--scheduler", "local", "--workers", "2", "--out", str(out), "--quiet",
                             "--no-certificates"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "TMPDIR": str(temp)}, start_new_session=True)
    deadline = time.monotonic() + 60
    while len(list(out.glob("runs/*/trajectory.csv"))) < 2:                # both runs stepping
        assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    time.sleep(1.5)                                                        # and hung at steps 20 and 21
    os.killpg(proc.pid, signum) if group else proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        raise
    assert proc.returncode == 128 + signum, err
    assert err.strip().splitlines()[-1] == "interrupted: sweep stopped after 2 of 3 runs; results so far are on disk"
    runs = json.loads((out / "runs.json").read_text())["runs"]
    assert [(r["status"], r["steps"]) for r in runs] == [("interrupted", 20), ("interrupted", 21)]
    verb = "interrupted by the user" if signum == signal.SIGINT else "stopped by SIGTERM"
    for run in runs:
        assert run["message"].startswith(f"{verb} at step {run['steps']}"), run["message"]
        assert run["message"].endswith("inside subsystem B (monolithic reference) in fmi2DoStep"), run["message"]
        folder = next((out / "runs").glob(f"{run['index']}_*"))
        assert json.loads((folder / "summary.json").read_text())["status"] == "interrupted"
        assert len((folder / "trajectory.csv").read_text().splitlines()) == run["steps"] + 2      # header, t = 0
    time.sleep(1.0)                                                        # janitors finish within a second
    assert survivors(temp) == [] and list(temp.iterdir()) == []
