"""The shared memory of a durable table (a supervised run's, run/recorder.py): its two blocks of rows
and a record of the rows they hold, mapped (MAP_SHARED) from files in the run's channel folder
(run/channel.py). A value written there is in the page cache at once, so when the child is killed
outright (SIGKILL, _exit, memory exhausted, every file descriptor closed) its parent still reads every
row it committed and appends those its CSV file lacks (run/salvage.py).

    <prefix>.record    int64: rows counted, rows with every column, each block's first row, and the rows
                       and bytes in the file, twice (the pair `which` names is whole: a death between
                       two stores leaves the other)
    <prefix>.block0/1  float64 (BLOCK + PAD) x columns, columns contiguous, as the table's blocks
    texts.jsonl        [column, text] per line: the texts of String outputs, in the order met (TextLog)
"""
import json
import mmap
import os
from pathlib import Path

import numpy as np

ROWS, WHOLE, FIRST, WHICH, FILED = 0, 1, 2, 4, 5     # record: rows counted, rows with every column, blocks' first
RECORD = FILED + 4                                    # rows, which (rows, bytes in the file) pair of the two holds


def mapped(prefix, rows, ld, columns):
    """A table's Mapped made afresh, or None when its folder cannot hold it (full, over the process's
    file size limit): the table then keeps its rows in the process's own memory."""
    try:
        return Mapped(prefix, rows, ld, columns)
    except OSError:
        return None


class Mapped:
    """A table's record and blocks mapped from files `prefix`.*: made afresh (create; their room taken on
    disk at once, so a write to them never meets a full disk) by the table, read back by the parent.
    A block holds `rows` rows of `columns` columns, `ld` doubles apart."""

    def __init__(self, prefix, rows, ld, columns, create=True):
        self.prefix, self.rows, self.shape = Path(prefix), rows, (ld, columns)
        self._record = self._map("record", 8 * RECORD, create)
        self.record = memoryview(self._record).cast("q")
        self.address = np.frombuffer(self._record, np.int64).ctypes.data      # of record[ROWS], for C
        size = 8 * ld * columns
        self._blocks = {slot: self._map(f"block{slot}", size, create) for slot in ((0, 1) if create else ())}
        if create:
            self.record[FIRST], self.record[FIRST + 1] = -1, -1

    def _map(self, name, size, create):
        path = self.prefix.with_suffix(f".{name}")
        fd = os.open(path, os.O_RDWR | (os.O_CREAT | os.O_TRUNC if create else 0), 0o600)
        try:
            if create:
                os.posix_fallocate(fd, 0, size)
            return mmap.mmap(fd, size)
        finally:
            os.close(fd)

    def block(self, slot, create=True):
        """Block `slot` (0 or 1) as a Fortran-order array of the full shape (NaN when made afresh)."""
        if slot not in self._blocks:
            self._blocks[slot] = self._map(f"block{slot}", 8 * self.shape[0] * self.shape[1], create)
        block = np.ndarray(self.shape, float, buffer=self._blocks[slot], order="F")
        if create:
            block[:] = np.nan
        return block

    def taken(self, slot, first):
        """Block `slot` holds rows from `first` on (its rows before are in the file)."""
        self.record[FIRST + slot] = first

    def count(self, rows):
        """`rows` rows are committed, every column of each written."""
        self.record[WHOLE] = self.record[ROWS] = rows

    def wrote(self, rows, size):
        """The file holds `rows` rows in `size` bytes (its writer says after each write)."""
        record, other = self.record, 1 - self.record[WHICH]
        record[FILED + 2 * other], record[FILED + 2 * other + 1] = rows, size
        record[WHICH] = other

    def filed(self):
        """(rows, bytes) in the file, as its writer last said."""
        which = self.record[WHICH]
        return self.record[FILED + 2 * which], self.record[FILED + 2 * which + 1]

    def rows_at(self, first, upto):
        """[(slot, row in it, count)] covering table rows first .. upto - 1 (those the blocks hold)."""
        out, at = [], first
        starts = sorted(((self.record[FIRST + s], s) for s in (0, 1) if self.record[FIRST + s] >= 0), reverse=True)
        while at < upto:
            slot = next(((s, start) for start, s in starts if start <= at < start + self.rows), None)
            if slot is None:
                break
            s, start = slot
            k = min(upto, start + self.rows) - at
            out.append((s, at - start, k))
            at += k
        return out


class TextLog:
    """The texts a durable run's String outputs meet (their columns' lists, which grow), appended to a
    file before a row holding them is counted, so the parent writes them in the rows it writes."""

    def __init__(self, path, columns):
        self.path, self.columns, self.known = path, columns, {j: 0 for j in columns}
        self.fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o600)

    def note(self):
        """Append the texts met since the last call."""
        for j, texts in self.columns.items():
            if len(texts) > self.known[j]:
                try:
                    os.write(self.fd, "".join(json.dumps([j, t]) + "\n" for t in texts[self.known[j]:]).encode())
                except OSError:           # the descriptor closed under it (an FMU did): those texts are left empty
                    pass
                self.known[j] = len(texts)


def texts_met(path):
    """{column: its texts} from a TextLog's file (a last line cut by a death left out)."""
    met = {}
    try:
        lines = Path(path).read_text().split("\n")[:-1]
    except OSError:
        return met
    for line in lines:
        j, text = json.loads(line)
        met.setdefault(j, []).append(text)
    return met
