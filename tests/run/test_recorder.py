"""run/recorder.py: tables stream to CSV in blocks and read back bit for bit, JSON and
MAT files, and Ctrl-C held until a step is booked."""
import errno
import json
import os
import signal
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat

from wavecosim.errors import OutputError
from wavecosim.run import recorder, writer
from wavecosim.run.recorder import Interrupts, Labels, Table, ints, write_json, write_mat


def fill(table, rows):
    for r in rows:
        table.next_row()[:] = r
        table.commit_row()


def awkward_rows(n, rng):
    """Rows whose floats need all 17 digits, plus ints, labels and non-finite values."""
    rows = np.column_stack([np.arange(n) / 100.0, rng.integers(0, 50, n), rng.standard_normal(n) * 1e-13,
                            rng.integers(0, 3, n), rng.standard_normal(n) * 1e200])
    rows[3, 2], rows[4, 4] = np.nan, np.inf
    return rows


@pytest.mark.parametrize("keep", [True, False], ids=["in-memory", "read-back"])
def test_table_round_trips_bit_for_bit_across_blocks(tmp_path, monkeypatch, keep):
    monkeypatch.setattr(recorder, "BLOCK", 7)
    if not keep:
        monkeypatch.setattr(recorder, "KEEP_VALUES", 0)
    rows = awkward_rows(50, np.random.default_rng(1))
    table = Table(["time", "n", "x", "why", "y"], tmp_path / "t.csv", expected_rows=50,
                  formats={"n": ints, "why": Labels(["budget", "tolerance", "deadline"])})
    fill(table, rows)
    table.close()
    back = table.array()
    assert back.tobytes() == rows.tobytes()
    lines = (tmp_path / "t.csv").read_text().splitlines()
    assert lines[0] == "time,n,x,why,y" and len(lines) == 51
    assert lines[4].split(",")[2] == "nan" and lines[5].split(",")[4] == "inf"
    assert lines[31].split(",")[0] == "0.3" and lines[2].split(",")[3] in ("budget", "tolerance", "deadline")


def test_table_without_file_keeps_everything(monkeypatch):
    monkeypatch.setattr(recorder, "KEEP_VALUES", 0)        # a table with no file has nowhere else to keep rows
    table = Table(["a"], None, expected_rows=10 ** 9)
    fill(table, [[float(k)] for k in range(3000)])
    assert table.array()[:, 0].tolist() == [float(k) for k in range(3000)]


def test_rows_reach_the_file_block_by_block(tmp_path, monkeypatch):
    """A failure after a block loses nothing of that block: it is on disk before the run ends (once
    its writer thread is done: wait() is what close() does first)."""
    monkeypatch.setattr(recorder, "BLOCK", 4)
    table = Table(["a"], tmp_path / "a.csv")
    fill(table, [[1.0]] * 9)
    table.wait()
    assert len((tmp_path / "a.csv").read_text().splitlines()) == 1 + 8


def test_json_is_written_whole_with_non_finite_values_as_text(tmp_path):
    write_json(tmp_path / "s.json", {"x": float("nan"), "y": np.float64(2.5), "p": tmp_path, "l": [np.int64(3)]})
    data = json.loads((tmp_path / "s.json").read_text())
    assert data == {"x": "nan", "y": 2.5, "p": str(tmp_path), "l": [3]}
    assert not list(tmp_path.glob("*.part"))


def test_mat_file_has_one_variable_per_column(tmp_path):
    table = Table(["time", "q1", "2x"], tmp_path / "t.csv")
    fill(table, [[0.0, 1.5, 2.0], [0.01, -1.0, 3.0]])
    table.close()
    write_mat(tmp_path / "t.mat", table)
    mat = loadmat(str(tmp_path / "t.mat"))
    assert mat["time"].ravel().tolist() == [0.0, 0.01] and mat["q1"].ravel().tolist() == [1.5, -1.0]
    assert mat["v_2x"].ravel().tolist() == [2.0, 3.0]


def test_ctrl_c_is_held_until_checked_and_a_second_one_goes_through():
    before = signal.getsignal(signal.SIGINT)           # ignored where the shell started us in the background
    with Interrupts() as stop:
        os.kill(os.getpid(), signal.SIGINT)
        assert stop.pending
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            stop.check()
    assert signal.getsignal(signal.SIGINT) is before


def written_table(path, rows, **kw):
    table = Table(["time", "n", "x", "why", "y"], path, formats={"n": ints, "why": Labels(["a", "b", "c"])}, **kw)
    table.append_block(rows)
    table.close()
    return path.read_bytes()


class NoThreadFree:
    """A pool whose threads never come to the work: the thread waiting for the rows formats them."""

    def submit(self, fn):
        pass


def test_file_is_the_same_whatever_the_writer_threads(tmp_path, monkeypatch):
    """Blocks handed over one after the other, formatted by the writer threads or by the thread that
    waits for them, in C or in Python, land in order."""
    monkeypatch.setattr(recorder, "BLOCK", 100)
    rows = awkward_rows(2_000, np.random.default_rng(4))
    threads = written_table(tmp_path / "threads.csv", rows)
    monkeypatch.setattr(writer, "pool", lambda: NoThreadFree())
    waiter = written_table(tmp_path / "waiter.csv", rows)
    monkeypatch.setattr(recorder, "block_writer", lambda block, kinds: None)     # formatted in Python
    python = written_table(tmp_path / "python.csv", rows)
    assert threads == waiter == python and threads.count(b"\r\n") == 2_001


def pieces_table(path, rows, sizes):
    """The rows committed in pieces of `sizes` (cycled), each handed to the writer as it is filled."""
    table = Table(["time", "n", "x", "why", "y"], path, formats={"n": ints, "why": Labels(["a", "b", "c"])})
    at, k = 0, 0
    while at < len(rows):
        count = min(sizes[k % len(sizes)], len(rows) - at)
        table.reserve(count)[:] = rows[at:at + count]
        table.commit_rows(count)
        table.hand_over()
        at, k = at + count, k + 1
    table.close()
    return path.read_bytes()


@pytest.mark.parametrize("formatter", ["C", "Python"])
def test_pieces_handed_over_as_they_are_filled_give_the_same_file(tmp_path, monkeypatch, formatter):
    """Rows handed to the writer threads piece by piece (a block of macro-steps at a time, several
    pieces per table block, formatted by two threads at once) land as one whole-block write would."""
    monkeypatch.setattr(recorder, "BLOCK", 100)
    if formatter == "Python":
        monkeypatch.setattr(recorder, "block_writer", lambda block, kinds: None)
    rows = awkward_rows(2_000, np.random.default_rng(5))
    whole = written_table(tmp_path / "whole.csv", rows)
    assert pieces_table(tmp_path / "pieces.csv", rows, [1, 7, 30, 13, 49]) == whole
    assert pieces_table(tmp_path / "one.csv", rows, [1]) == whole


def test_a_writer_error_is_raised_at_the_next_flush_and_at_close(monkeypatch):
    """/dev/full: every write fails with ENOSPC (disk full), in the writer thread: one OutputError naming
    the file, raised again by every later call."""
    monkeypatch.setattr(recorder, "BLOCK", 10)
    table = Table(["a"], Path("/dev/full"))
    fill(table, [[1.0]] * 10)                      # the block is full; the next row hands it over
    with pytest.raises(OutputError) as first:
        table.next_row()                           # raises when the writer thread failed already
        table.wait()
    table.next_row()
    table.commit_row()
    with pytest.raises(OutputError) as again:
        table.flush()
    with pytest.raises(OutputError) as at_close:
        table.close()
    assert first.value is again.value is at_close.value and first.value.__cause__.errno == errno.ENOSPC
    assert str(first.value) == "/dev/full: cannot write: No space left on device"


def test_ctrl_c_while_closing_is_held_until_every_row_is_written(tmp_path):
    """A Ctrl-C that comes while the last rows are being written (here: from the writer thread itself)
    is raised by close() once they are all in the file."""
    def slow_floats(col):
        if col[-1] == -1.0:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        return list(map(repr, col.tolist()))

    table = Table(["a"], tmp_path / "a.csv", formats={"a": slow_floats})
    fill(table, [[float(k)] for k in range(500)] + [[-1.0]])
    with pytest.raises(KeyboardInterrupt):
        table.close()
    assert len((tmp_path / "a.csv").read_text().splitlines()) == 1 + 501


def test_a_forked_child_writes_with_threads_of_its_own(tmp_path):
    """The writer threads are made again in a forked child (a process pool's worker): the parent's
    do not exist there."""
    written_table(tmp_path / "parent.csv", awkward_rows(10, np.random.default_rng(6)))    # the parent's pool
    pid = os.fork()
    if pid == 0:
        status = 1
        try:
            status = 0 if writer.pool().submit(lambda: 7).result(timeout=10) == 7 else 1
            table = Table(["a"], tmp_path / "child.csv")
            fill(table, [[0.5]] * 3)
            table.close()
        finally:
            os._exit(status)
    assert os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) == 0
    assert (tmp_path / "child.csv").read_text().splitlines() == ["a", "0.5", "0.5", "0.5"]


def durable_tables(folder, rows, texts):
    """A run's two tables as a supervised run makes them (durable, described in rows.json), filled
    with `rows`: the trajectory one ahead (its row at t = 0), row by row and in pieces handed over."""
    memory = folder / "rows-1"
    memory.mkdir()
    formats = {"n": ints, "why": Labels(["a", "b", "c"]), "label": recorder.Texts(texts)}
    tables = {kind: Table(["time", "n", "x", "why", "label"], folder / f"{kind}.csv", formats=formats,
                          expected_rows=len(rows), durable=memory / kind) for kind in ("trajectory", "steps")}
    (memory / "rows.json").write_text(json.dumps({kind: t.described([4]) for kind, t in tables.items()}))
    fill(tables["trajectory"], rows[:1])
    for at in range(0, len(rows) - 1, 300):
        piece = rows[1 + at:1 + at + 300]
        for table, part in ((tables["steps"], piece), (tables["trajectory"], piece)):
            table.append_block(part)
            table.hand_over()
    return tables


def test_a_process_killed_outright_leaves_every_committed_row_to_its_parent(tmp_path):
    """A durable table's rows are in memory the parent reads after the child died without writing
    them (os._exit: no writer finished, no file closed): the parent writes the file the child would
    have, bit for bit (floats, integers, labels, texts), however far its writer threads had come."""
    rows = awkward_rows(2_600, np.random.default_rng(7))[:, :5]
    rows[:, 4] = np.arange(len(rows)) % 2
    whole = tmp_path / "whole"
    whole.mkdir()
    for table in durable_tables(whole, rows, ["x", 'say "y"']).values():
        table.close()
    pid = os.fork()
    if pid == 0:
        try:
            durable_tables(tmp_path, rows, ["x", 'say "y"'])
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    from wavecosim.run.salvage import complete_rows
    complete_rows(tmp_path)
    for kind in ("trajectory", "steps"):
        assert (tmp_path / f"{kind}.csv").read_bytes() == (whole / f"{kind}.csv").read_bytes()
    assert (tmp_path / "steps.csv").read_bytes().count(b"\n") == len(rows)


def test_a_disk_that_fills_under_the_parent_leaves_whole_rows(tmp_path):
    """The parent's disk fills while it writes the rows a killed child left (a file size limit): the
    files end with the last whole row it took, each table on its own."""
    import resource
    rows = awkward_rows(2_600, np.random.default_rng(8))[:, :5]
    pid = os.fork()
    if pid == 0:
        try:
            durable_tables(tmp_path, rows, ["x"])
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    sizes = {kind: (tmp_path / f"{kind}.csv").stat().st_size for kind in ("trajectory", "steps")}
    pid = os.fork()
    if pid == 0:
        try:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (max(sizes.values()) + 5_000,) * 2)
            from wavecosim.run.salvage import complete_rows
            complete_rows(tmp_path)
        finally:
            os._exit(0)
    os.waitpid(pid, 0)
    for kind, size in sizes.items():
        data = (tmp_path / f"{kind}.csv").read_bytes()
        assert data.endswith(b"\r\n") and len(data) <= size + 5_000
        assert len({line.count(b",") for line in data.split(b"\r\n")[:-1]}) == 1
