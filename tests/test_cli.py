"""The command line's progress display: on a terminal click's progress bar with the steps, the
percentage, the time elapsed and the ETA; elsewhere (a pipe, a log file) one line when done."""
import os
import subprocess

import pytest

from paths import CLI

pty = pytest.importorskip("pty")
RUN = ["run", "--T", "50", "--no-reference", "--no-certificates"]


def on_a_terminal(args, cwd):
    """stderr of the command line run with a pseudo-terminal as stderr."""
    master, slave = pty.openpty()
    try:
        subprocess.run(CLI + args, stdout=subprocess.DEVNULL, stderr=slave, cwd=cwd, check=True, timeout=120)
    finally:
        os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 1 << 16)
        except OSError:                     # the terminal's other end is closed: all was read
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    return out.decode()


def test_a_run_on_a_terminal_shows_a_bar_with_elapsed_time_and_eta(tmp_path, built_fmus):
    lines = [line for line in on_a_terminal(RUN + ["--out", "out"], tmp_path).split("\r") if "run  [" in line]
    assert len(lines) >= 3 and "5000/5000  100%" in lines[-1] and " s elapsed" in lines[-1]
    assert any(" s elapsed, ETA " in line for line in lines[:-1])


def test_elsewhere_a_run_ends_with_one_line(tmp_path, built_fmus):
    done = subprocess.run(CLI + RUN + ["--out", "out"], capture_output=True, text=True, cwd=tmp_path, check=True)
    lines = done.stderr.splitlines()
    assert [line for line in lines if "steps" in line] == [next(line for line in lines if line.startswith(
        "  run: 5000/5000 steps done in "))]
    assert "[" not in done.stderr
