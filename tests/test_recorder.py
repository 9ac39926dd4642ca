"""master/observers/recorder.py: tables stream to CSV in blocks and read back bit for bit, JSON and
MAT files, and Ctrl-C held until a step is booked."""
import json
import os
import signal

import numpy as np
import pytest
from scipy.io import loadmat

from wavecosim.observers import recorder
from wavecosim.observers.recorder import Interrupts, Labels, Table, ints, write_json, write_mat


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
    """A failure after a block loses nothing of that block: it is on disk before the run ends."""
    monkeypatch.setattr(recorder, "BLOCK", 4)
    table = Table(["a"], tmp_path / "a.csv")
    fill(table, [[1.0]] * 9)
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
    with Interrupts() as stop:
        os.kill(os.getpid(), signal.SIGINT)
        assert stop.pending
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
        with pytest.raises(KeyboardInterrupt):
            stop.check()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
