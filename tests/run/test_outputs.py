"""The output folder: a new run replaces an earlier run's files wholly, a folder holding anything else
is refused unless --overwrite, a second run cannot write into a folder in use, and an unwritable
folder or a full disk is one line (exit 7) with no row cut in the middle."""
import fcntl
import json
import os
import resource
import signal
import subprocess

import pytest

from paths import CLI
from wavecosim.errors import OutputError
from wavecosim.run.outputs import LOCK, OutputFolder


def run(out, *extra, **kw):
    return subprocess.run([*CLI, "run", "--T", "0.2", "--out", str(out), "--quiet", "--no-certificates", *extra],
                          capture_output=True, text=True, timeout=120, **kw)


def test_a_new_run_replaces_the_earlier_runs_files_wholly(tmp_path):
    out = tmp_path / "out"
    first = run(out, "--format", "mat")
    assert first.returncode == 0, first.stderr
    assert {"trajectory.mat", "summary_monolithic.json"} <= {p.name for p in out.iterdir()}
    second = run(out, "--no-reference")
    assert second.returncode == 0, second.stderr
    assert sorted(p.name for p in out.iterdir()) == ["metadata.json", "steps.csv", "summary.json", "trajectory.csv"]


def test_a_folder_with_other_files_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    refused = run(out)
    assert refused.returncode == 7 and refused.stderr.strip() == (
        f"error: {out}: holds files that are not a wavecosim run's (notes.txt); choose another --out, or pass "
        f"--overwrite to write beside them")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    allowed = run(out, "--overwrite")
    assert allowed.returncode == 0 and (out / "notes.txt").read_text() == "mine"
    assert (out / "summary.json").exists() and not (out / LOCK).exists()


def test_a_second_run_cannot_write_into_a_folder_in_use(tmp_path):
    out = tmp_path / "out"
    with OutputFolder(out):
        assert (out / LOCK).read_text().strip() == str(os.getpid())
        busy = run(out)
    assert busy.returncode == 7
    assert busy.stderr.strip() == (f"error: {out}: another run is writing into this folder (process {os.getpid()}); "
                                   f"wait for it or choose another --out")
    assert not (out / LOCK).exists() and run(out).returncode == 0


def test_the_lock_goes_with_the_process_that_held_it(tmp_path):
    """A run killed outright leaves its lock file, but not the lock: the next run goes ahead."""
    out = tmp_path / "out"
    out.mkdir()
    holder = subprocess.Popen(["python3", "-c", "import fcntl, os, sys, time; fd = os.open(sys.argv[1], os.O_RDWR | "
                               "os.O_CREAT); fcntl.flock(fd, fcntl.LOCK_EX); print(1, flush=True); time.sleep(60)",
                               str(out / LOCK)], stdout=subprocess.PIPE)
    holder.stdout.readline()
    with pytest.raises(OutputError, match="another run is writing"):
        OutputFolder(out)
    holder.send_signal(signal.SIGKILL)
    holder.wait()
    assert (out / LOCK).exists()
    with OutputFolder(out):
        fd = os.open(out / LOCK, os.O_RDWR)
        with pytest.raises(BlockingIOError):
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.close(fd)


def test_an_unwritable_output_folder_is_one_line(tmp_path):
    proc = run("/proc/wavecosim-out")
    assert proc.returncode == 7 and proc.stderr.strip().startswith(
        "error: /proc/wavecosim-out: cannot create the output folder: ")


def test_a_full_disk_is_one_line_and_no_row_is_cut(tmp_path):
    """Files may not grow past 100 kB (RLIMIT_FSIZE: writes then fail as on a full disk, with EFBIG)."""
    out = tmp_path / "out"

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))
    proc = subprocess.run([*CLI, "run", "--T", "20", "--out", str(out), "--quiet", "--no-reference"],
                          capture_output=True, text=True, timeout=120, preexec_fn=small_files)
    assert proc.returncode == 7, proc.stderr
    line = proc.stderr.strip()
    assert "\n" not in line and line.startswith("error: ") and ": cannot write: File too large" in line
    for name in ("trajectory.csv", "steps.csv"):
        data = (out / name).read_bytes()
        assert data.endswith(b"\r\n")
        widths = {row.count(b",") for row in data.split(b"\r\n")[:-1]}
        assert len(widths) == 1                                   # header and rows: whole lines only


def test_summary_of_a_run_refused_before_it_starts_is_not_written(tmp_path):
    """A bad option stops before the folder is touched: the earlier run's files stay."""
    out = tmp_path / "out"
    assert run(out).returncode == 0
    before = json.loads((out / "summary.json").read_text())
    assert run(out, "--dt", "nan").returncode == 2
    assert json.loads((out / "summary.json").read_text()) == before
