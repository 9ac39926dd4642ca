"""Runtime concerns of a run, each in one place, all behind one small interface.

The runner asks each observer once, before the loop, which per-step columns it fills and whether
it needs the master's inner queries; an observer that is off is simply not in the list, so it
costs nothing. Per macro-step the runner calls `before_step`, then the master (whose own guard may
redo the step), reads the FMUs, then calls `after_step` in list order; observers read what the step
logged and the FMUs' values, write their columns, and change nothing. When every observer has
`blocks` set, the runner may run many macro-steps in one call of the master and give them to
`after_block` at once (or to its `block_pass`, which the kernel makes as it goes); its figures must
equal, to the last bit, those of `after_step` called step by step. A `paced` observer acts before
some steps only (`next_before`): blocks run between them.
"""
import re

import numpy as np

from ...kernel.drkernel import LEDGER_LOG

SUBSYSTEM = "<subsystem>"     # stands for a subsystem's name in a column pattern


def described_as(described, column):
    """(meaning, unit) of a column from a table {name or pattern: (meaning, unit)}, where <subsystem>
    in a pattern stands for a subsystem's name; None when the table does not describe it."""
    for pattern, entry in described.items():
        if re.fullmatch(re.escape(pattern).replace(re.escape(SUBSYSTEM), ".+"), column):
            return entry
    return None


class Observer:
    """Base of the runtime concerns (certificates, the ledger's columns, gamma tuner, Condition 1 watch)."""
    columns = ()          # per-step columns it fills (steps.csv), in order
    described = {}        # every column it may fill -> (meaning, unit); docs/outputs.md is generated from it
    when = ""             # when a run has it (docs/outputs.md)
    formats = {}          # column -> formatter for steps.csv (default: floats), e.g. recorder.Labels
    needs_trace = False   # it reads the master's inner queries (u^k, S(u^k)) of each step
    blocks = False        # it has after_block or a block_pass (and nothing to do before a step, unless paced)
    paced = False         # it acts before the steps next_before() names only, and blocks may run between

    def start(self, first):
        """Once, with the Reading of the FMUs at t = 0, before the first macro-step."""

    def before_step(self, n, t):
        """Before macro-step n (the FMUs are at x^n)."""

    def next_before(self, n):
        """A paced observer: the first macro-step >= n before which it acts (math.inf: none)."""
        raise NotImplementedError

    def block(self, n0, logs, readings):
        """Its columns over macro-steps n0 .. n0 + steps - 1 as an array (steps x columns), from the
        steps' log (a BlockLog, or a StepLog as a block of one: OneStep) and the FMUs' values after
        each (a BlockReading, or a Reading as a block of one: OneReading), in numpy: the one definition
        of its columns, step by step and in blocks alike. None where the observer writes its columns
        in after_step and after_block instead."""
        return None

    def after_step(self, n, t, log, reading, row):
        """After macro-step n: `reading` holds the FMUs' values at x^{n+1}; write this observer's
        columns into `row` (its own slice of the step row, in the order of `columns`). By default
        the first row of block() over this step alone."""
        columns = self.block(n, OneStep(log), OneReading(reading))
        if columns is not None:
            row[:] = columns[0]

    def prepare_block(self, logs, readings):
        """In set-up, before any block: `logs` and `readings` are empty (no step) but laid out as the
        blocks' will be, so what after_block builds once can be built here, outside the run's time."""

    def block_pass(self):
        """Its columns of a block's steps as a pass in C (kernel/blocks.py, Pass; built by prepare_block),
        which the kernel makes as it logs the steps and the runner over the rest, in place of
        after_block; None when it has none. The runner sets its arguments' `out` (the block's first
        row of these columns) and `ldo` (doubles between them) where it has columns."""
        return None

    def before_passes(self):
        """Before a kernel call whose steps its block_pass makes: hand the pass what after_step carried on."""

    def after_passes(self):
        """After a block whose steps its block_pass made: what it says of them itself (a warning)."""

    def after_block(self, n0, logs, readings, rows, at=None):
        """After macro-steps n0 .. n0 + len(rows) - 1 made in one call: `logs` (fast_path.BlockLog)
        and `readings` (readings.BlockReading) hold one row per step; write this observer's columns
        into `rows` (steps x its columns), exactly as after_step would, step after step. `at`: where
        rows lives for a pass in C (address of its first value, doubles between columns), or None.
        By default block() over the steps."""
        rows[:] = self.block(n0, logs, readings)

    def summary(self) -> dict:
        """Its figures for summary.json."""
        return {}

    def verdict(self):
        """Why a run that went to its end is suspect (e.g. a frozen FMU), or None."""
        return None

    def unit(self, column):
        """The unit of one of its columns (metadata.json), from `described`."""
        entry = described_as(self.described, column)
        return entry[1] if entry else ""


class OneStep:
    """A StepLog as a block of one step: the fields a BlockLog gives as arrays, one row or column."""

    def __init__(self, log):
        self.log = log

    def __len__(self):
        return 1

    iterations = property(lambda self: np.array([float(self.log.iterations)]))
    residual = property(lambda self: np.array([self.log.residual]))
    a_hat = property(lambda self: np.array([self.log.a_hat], dtype=float))

    @property
    def ledger_rows(self):
        """The energy ledger's figures as the kernel logs them (LEDGER_LOG x 1; NaN where not kept)."""
        rows = np.full((len(LEDGER_LOG), 1), np.nan)
        rows[[0, 1, 3, 4, 5], 0] = self.log.ledger                # supplied, ledger; scale, action, rounds
        return rows


class OneReading:
    """A Reading as a block of one step: H, E, F, B and outputs as BlockReading's (one row each)."""

    def __init__(self, reading):
        self.reading = reading

    def __getattr__(self, key):
        if key not in ("H", "E", "F", "B", "outputs"):
            raise AttributeError(key)
        return np.array([getattr(self.reading, key)], dtype=float)
