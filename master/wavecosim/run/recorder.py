"""The recorder: owns a run's rows, its CSV (and MAT) files and the Ctrl-C handling.

Rows go into preallocated blocks of BLOCK rows and are written to disk a block at a time, so a
failure or Ctrl-C loses nothing already computed and memory does not grow with the run: a table
keeps all its rows in memory only while they fit in KEEP_VALUES numbers (or when it has no file);
beyond that it reads them back from its file when asked. Every float is written as repr writes it
(the shortest text that reads back to the same bits): a block at a time in C (wavecosim/kernel/csvfmt.py),
or with repr itself when the C formatter is not built or a column has a formatter of its own.
"""
import csv
import io
import json
import math
import os
import re
import signal
import threading
from functools import partial
from pathlib import Path

import numpy as np

from ..kernel.csvfmt import block_writer
from .durable import mapped
from .outputs import cannot
from .writer import Writer

BLOCK = 1024
PAD = 8                           # columns BLOCK + PAD apart: 8 KiB apart they would share cache sets
KEEP_VALUES = 262_144             # 2 MB of rows per table at most stays in memory


def _floats(col):
    return list(map(repr, col.tolist()))


def _ints(col):
    return [str(int(v)) for v in col.tolist()]


class Labels:
    """A formatter writing code k of a column as names[k] (e.g. the reason an inner loop stopped)."""

    def __init__(self, names):
        self.names = list(names)

    def __call__(self, col):
        return [self.names[int(v)] for v in col.tolist()]

    def parse(self, cells):
        return [self.names.index(v) for v in cells]


class Texts:
    """A formatter writing code k of a column as the k-th of `texts` (a list that grows as the run
    meets new texts), quoted as CSV quotes text: in double quotes, a quote doubled."""

    def __init__(self, texts):
        self.texts = texts

    def __call__(self, col):
        return [quoted(self.texts[int(v)]) for v in col.tolist()]

    def parse(self, cells):
        index = {t: k for k, t in enumerate(self.texts)}
        return [index.setdefault(c, len(index)) for c in cells]


def quoted(text):
    """A CSV cell holding `text` as it is (RFC 4180)."""
    return '"' + text.replace('"', '""') + '"'


def header(columns):
    """The CSV header line's cells: a name holding a comma, quote or line break is quoted."""
    return ",".join(quoted(c) if any(ch in c for ch in ',"\r\n') else c for c in columns)


class Table:
    """One table of float rows (`columns`), streamed to `path` (CSV) when given.

    `formats` maps a column to a formatter (default repr of floats); see `ints` and `Labels`.
    Rows fill one of two blocks; a full block is handed to the writer threads (run/writer.py)
    while the other fills, and is filled again only once its rows are formatted (a table that keeps
    its rows in memory keeps its full blocks themselves and takes fresh ones).

    durable (a path prefix; with a file only): the blocks and the count of rows committed live in
    shared memory mapped from files there (run/durable.py), and a block is filled again only once
    its rows are in the file, so a process killed outright loses no committed row (run/salvage.py)."""

    def __init__(self, columns, path=None, formats=None, expected_rows=0, durable=None):
        self.columns, self.path = list(columns), path
        self._fmt = [(formats or {}).get(c, _floats) for c in self.columns]
        self.shared = mapped(durable, BLOCK, BLOCK + PAD, len(self.columns)) if durable and path else None
        self._slots = [self._new_slot(0), None]       # (block, its formatter); the second made when first needed
        self._pending = [[], []]                      # each block's hand-overs not yet settled (writer Pieces)
        self._at, self._fill, self._handed = 0, 0, 0  # block in use, rows filled, rows of it handed over
        self.ld = BLOCK + PAD                         # doubles between a block's columns
        self._block, self._block_at = self._slots[0][0], self._slots[0][0].ctypes.data
        if self.shared is not None:
            self.shared.taken(0, 0)
        self._kept = [] if path is None or expected_rows * len(self.columns) <= KEEP_VALUES else None
        self.rows = 0
        self._file, self._writer = None, None
        if path is not None:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                self._file = open(path, "wb")
                self._file.write((header(self.columns) + "\r\n").encode())
            except OSError as exc:
                raise cannot(path, exc) from None
            self._writer = Writer(self._file, self.shared)

    def _new_slot(self, at):
        """A block of BLOCK rows (columns contiguous) and what formats its rows for the file (slot `at`)."""
        if self.shared is not None:
            block = self.shared.block(at)[:BLOCK]
        else:
            block = np.full((BLOCK + PAD, len(self.columns)), np.nan, order="F")[:BLOCK]    # touched here, not in the loop
        if self.path is None:
            return block, None
        return block, block_writer(block, [_kind(f) for f in self._fmt]) or self._python_text(block)

    @property
    def formats(self):
        """Each column's formatter, in column order."""
        return list(self._fmt)

    def described(self, late=()):
        """What the parent of a durable run needs to write this table's rows from its shared memory
        (run/salvage.py): the file, the columns and their formats, the memory's files; late: the
        columns filled only once a block of steps is made (left empty in the rows of a block in progress)."""
        return {"csv": str(self.path), "columns": self.columns, "formats": [described(f) for f in self._fmt],
                "memory": str(self.shared.prefix), "late": list(late)}

    def next_row(self):
        """A row to fill in place (the block's next slot); it is booked by `commit_row`."""
        if self._fill == BLOCK:
            self.flush()
        if self._block is None:
            self._take_block()
        return self._block[self._fill]

    def commit_row(self):
        self._fill += 1
        self.rows += 1
        if self.shared is not None:
            self.shared.count(self.rows)

    def reserve(self, k):
        """k rows (k <= BLOCK) of the block to fill in place, booked by commit_rows(k)."""
        self.reserve_at(k)
        return self._block[self._fill:self._fill + k]

    def reserve_at(self, k):
        """reserve(k) for a pass in C: the address of the first of the k rows (columns `ld` doubles apart)."""
        if self._fill + k > BLOCK:
            self.flush()
        if self._block is None:
            self._take_block()
        return self._block_at + 8 * self._fill

    def commit_rows(self, k):
        self._fill += k
        self.rows += k
        if self.shared is not None:
            self.shared.count(self.rows)

    def append_block(self, rows):
        """Book many rows at once (a 2-D array of the table's columns), as next_row and commit_row would."""
        at = 0
        while at < len(rows):
            if self._fill == BLOCK:
                self.flush()
            if self._block is None:
                self._take_block()
            k = min(BLOCK - self._fill, len(rows) - at)
            self._block[self._fill:self._fill + k] = rows[at:at + k]
            self._fill, self.rows, at = self._fill + k, self.rows + k, at + k
            if self.shared is not None:
                self.shared.count(self.rows)

    def hand_over(self):
        """Hand the rows filled since the last hand-over to the writer threads now (the runner does after
        each block of macro-steps, so they are formatted while the master makes the next block)."""
        if self._writer is None or self._fill == self._handed:
            return
        self._writer.check()
        text = partial(self._slots[self._at][1], start=self._handed)
        self._pending[self._at].append(self._writer.hand_over(text, self._fill - self._handed))
        self._handed = self._fill

    def flush(self):
        """Hand the rest of the block to the writer (and keep it when the table stays in memory), then
        go on in the other block once its rows are formatted; raises a writer's error."""
        if self._writer is not None:
            self._writer.check()
        if not self._fill:
            return
        self.hand_over()
        if self._kept is not None and self.shared is not None:
            self._kept.append(self._block[:self._fill].copy())     # the shared block is filled again
        elif self._kept is not None:
            self._kept.append(self._block[:self._fill])      # the block itself: it is not filled again
            self._slots[self._at] = None
        self._at, self._fill, self._handed, self._block = 1 - self._at, 0, 0, None
        for piece in self._pending[self._at]:
            self._writer.settle(piece, written=self.shared is not None)
        self._pending[self._at] = []
        if self._writer is not None:
            self._writer.check()

    def _take_block(self):
        """Rows go next into the current slot's block, made when first needed (after a flush)."""
        self._slots[self._at] = self._slots[self._at] or self._new_slot(self._at)
        self._block = self._slots[self._at][0]
        self._block_at = self._block.ctypes.data
        if self.shared is not None:
            self.shared.taken(self._at, self.rows)

    def _python_text(self, block):
        """Rows start .. start + rows - 1 of `block` as CSV lines, formatted in Python."""
        def text(rows, start=0):
            cells = [fmt(block[start:start + rows, j]) for j, fmt in enumerate(self._fmt)]
            return "".join(",".join(r) + "\r\n" for r in zip(*cells)).encode()
        return text

    def wait(self):
        """Until every row handed over is in the file; raises a writer's error."""
        if self._writer is not None:
            self._writer.wait()

    def close(self):
        """Write every row and close the file; a Ctrl-C meanwhile is held until all is written (a table
        without a file has nothing to write: its rows stay where they are, and `array` reads them)."""
        if self._file is None:
            return
        with Interrupts() as held:
            try:
                self.flush()
                self.wait()
            finally:
                self._close_file()
        held.check()

    def _close_file(self):
        """Close the file once no writer thread uses it; after a writer's error (the one raised) the
        file's own complaint about its unwritten buffer is left out."""
        if self._file is None or self._file.closed:
            return
        failed = self._writer.wait_quietly()
        try:
            self._file.close()
        except OSError as exc:
            if not failed:
                raise cannot(self.path, exc) from None
        if failed:                      # what the failed write left of a row goes: whole rows only
            try:
                os.truncate(self.path, self._writer.written)
            except OSError:
                pass

    def array(self):
        """All rows as a 2-D float array (read back from the file when not kept in memory)."""
        if self._kept is not None:
            rows = self._kept + ([self._block[:self._fill].copy()] if self._fill else [])
            return np.concatenate(rows) if rows else np.empty((0, len(self.columns)))
        self.flush()
        self.wait()
        return _read_csv(self.path, self._fmt)


def _read_csv(path, formats):
    """A table's CSV back into floats (label and text columns back to their codes)."""
    with open(path, newline="") as f:
        if any(isinstance(fmt, Texts) for fmt in formats):
            rows = list(csv.reader(io.StringIO(f.read())))[1:]
        else:
            f.readline()
            rows = [line.rstrip("\r\n").split(",") for line in f if line.strip()]
    out = np.empty((len(rows), len(formats)))
    for j, fmt in enumerate(formats):
        col = [r[j] for r in rows]
        out[:, j] = fmt.parse(col) if isinstance(fmt, (Labels, Texts)) else np.array(col, float)
    return out


ints = _ints


def described(fmt):
    """A formatter as JSON (formatter() makes it again): "float", "int", {"labels": ...} or {"texts": ...}."""
    if isinstance(fmt, Labels):
        return {"labels": fmt.names}
    if isinstance(fmt, Texts):
        return {"texts": list(fmt.texts)}
    return "int" if fmt is _ints else "float"


def formatter(description):
    """The formatter `described` gave; a text the run met after it was described is left empty."""
    if isinstance(description, dict) and "labels" in description:
        return Labels(description["labels"])
    if isinstance(description, dict):
        texts = description["texts"]
        return lambda col: [quoted(texts[int(v)]) if 0 <= v < len(texts) else "" for v in col.tolist()]
    return _ints if description == "int" else _floats


def _kind(fmt):
    """What the C formatter calls a column's formatter: 0 floats, 1 integers, label names; None: unknown."""
    if isinstance(fmt, Labels):
        return fmt.names
    return {_floats: 0, _ints: 1}.get(fmt)


class Interrupts:
    """Holds Ctrl-C (SIGINT) and SIGTERM until the step in progress is booked: `pending` says one came
    (`signal` which), and `check()` raises KeyboardInterrupt between steps. A second one raises at once."""
    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __enter__(self):
        self.pending, self.signal, self._old = False, None, {}
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                self._old[sig] = signal.signal(sig, self._hold)
        return self

    def _hold(self, signum, frame):
        self.signal = self.signal or signum
        if self.pending:
            raise KeyboardInterrupt
        self.pending = True

    def check(self):
        if self.pending:
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False


def clean_json(obj):
    """JSON-safe copy: non-finite floats become strings, numpy scalars plain numbers."""
    if isinstance(obj, dict):
        return {str(k): clean_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (list, dict)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: Path, data):
    """Write JSON atomically (a .part file renamed), so a reader never sees half a file; an OSError
    (disk full, not writable) is an OutputError naming the file."""
    path = Path(path)
    tmp = path.with_suffix(".json.part")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(clean_json(data), indent=2) + "\n")
        tmp.replace(path)
    except OSError as exc:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise cannot(path, exc) from None


def write_mat(path: Path, table: Table):
    """The table as a MATLAB file (scipy.io.savemat), one variable per column (names made valid)."""
    from scipy.io import savemat
    data = table.array()
    names = [re.sub(r"\W", "_", c) if re.match(r"[A-Za-z]", c) else f"v_{re.sub(r'[^0-9A-Za-z]', '_', c)}"
             for c in table.columns]
    columns = [np.array([fmt.texts[int(v)] for v in data[:, j]], dtype=object) if isinstance(fmt, Texts)
               else data[:, j] for j, fmt in enumerate(table.formats)]          # texts as cell arrays
    savemat(str(path), dict(zip(names, columns)), oned_as="column")
