"""Error against the monolithic reference, computed as the run streams: per grid point
||(dq1, dq2, ...)||_2 over the scenario's error columns, and its max, time-RMS and final value; for a
scenario that names none, every Real output's largest |Δy| over the grid divided by its range."""
import math

import numpy as np

from ...fmi.values import REAL, category
from . import Observer


class ErrorTracker(Observer):
    """Column `error`; `reference(k)` gives the reference's outputs at grid point k (None: no more)
    and `reference_rows(k, count)` those of grid points k .. k + count - 1 as rows (fewer: no more)."""
    columns = ("error",)
    when = "a run with the monolithic reference and `error` columns"
    described = {"error": ("‖(Δy₁, Δy₂, …)‖₂ over the scenario's `error` columns against the monolithic "
                           "reference at the same grid point", "the error columns' units")}
    blocks = True

    def __init__(self, output_names, error_names, reference, reference_rows=None):
        self.idx = [output_names.index(c) for c in error_names]
        self.reference = reference
        self.reference_rows = reference_rows or (lambda k, count: rows_of(reference, k, count))
        self.max, self.sumsq, self.count, self.final = 0.0, 0.0, 0, math.nan
        self.first = math.nan

    def _error(self, outputs, k):
        ref = self.reference(k)
        if ref is None:
            return math.nan
        d = np.array([outputs[i] - ref[i] for i in self.idx])
        e = float(np.sqrt(np.sum(d * d)))
        self.max = max(self.max, e) if e == e else e
        self.sumsq += e * e
        self.count += 1
        self.final = e
        return e

    def start(self, first):
        self.first = self._error(first.outputs, 0)

    def after_step(self, n, t, log, reading, row):
        row[0] = self._error(reading.outputs, n + 1)

    def after_block(self, n0, logs, readings, rows, at=None):
        ref = self.reference_rows(n0 + 1, len(rows))
        have = len(ref)
        with np.errstate(over="ignore", invalid="ignore"):     # as Python floats overflow: inf, nan, silently
            d = readings.outputs[:have, self.idx] - ref[:, self.idx] if have else np.empty((0, 0))
            errors = np.sqrt(row_norms_squared(d * d))
        rows[:have, 0], rows[have:, 0] = errors, math.nan
        for e in errors.tolist():                       # running figures, in step order as after_step
            self.max = max(self.max, e) if e == e else e
            self.sumsq += e * e
            self.final = e
        self.count += have

    def summary(self):
        if not self.count:
            return {}
        return {"max_error": self.max, "rms_error": math.sqrt(self.sumsq / self.count), "final_error": self.final}


def stored_reference(result):
    """reference(k) from a finished RunResult's trajectory (all its output columns)."""
    outputs = result.outputs
    return lambda k: outputs[k] if k < len(outputs) else None


def row_norms_squared(sq):
    """np.sum of each row, as np.sum of that row alone: numpy adds fewer than 8 numbers in order
    either way, and longer rows pairwise only when summed alone."""
    return np.sum(sq, axis=1) if sq.shape[1] < 8 else np.array([np.sum(row) for row in sq])


def rows_of(reference, k, count):
    """Rows of reference(k), reference(k + 1), ... until count rows or the first None."""
    rows = []
    for j in range(k, k + count):
        row = reference(j)
        if row is None:
            break
        rows.append(row)
    return np.array(rows, dtype=float)


def stored_rows(result):
    """reference_rows(k, count) from a finished RunResult's trajectory."""
    outputs = result.outputs
    return lambda k, count: outputs[k:k + count]


def error_metrics(result, reference, columns):
    """The same figures after the fact, from two finished results: (error per grid point, metrics)."""
    n = min(len(result.t), len(reference.t))
    diff = np.stack([result.column(c)[:n] - reference.column(c)[:n] for c in columns], axis=1)
    err = np.sqrt(np.sum(diff * diff, axis=1))
    return err, {"max_error": float(err.max()), "rms_error": float(np.sqrt(np.mean(err * err))),
                 "final_error": float(err[-1])}


CONSTANT_TO_ROUNDOFF = 1e-9     # a range below this fraction of the column's magnitude: a constant column


def column_scales(low, high, peak):
    """Each column's scale: its range in the reference (max - min); a column constant to roundoff
    (range <= CONSTANT_TO_ROUNDOFF x its largest |value|) its largest |value| (a relative error); a
    column zero throughout 1 (its absolute error)."""
    span = high - low
    constant = ~(span > CONSTANT_TO_ROUNDOFF * peak)
    return np.where(constant, np.where(peak > 0, peak, 1.0), span)


class ScaledErrors(Observer):
    """Error against the monolithic reference over every recorded Real output, each column's |Δy|
    divided by the column's range in the reference (column_scales), the range known only at the end,
    so the figures are summary figures. `reference`, `reference_rows` as ErrorTracker's."""
    when = "a run with the monolithic reference"
    blocks = True

    def __init__(self, output_names, real, reference, reference_rows=None, figures=True):
        self.figures = figures           # max_error, rms_error, final_error too (else `errors` alone)
        self.names = [c for c, is_real in zip(output_names, real) if is_real]
        self.idx = [k for k, is_real in enumerate(real) if is_real]
        self.reference = reference
        self.reference_rows = reference_rows or (lambda k, count: rows_of(reference, k, count))
        width = len(self.idx)
        self.worst, self.sumsq, self.final = np.zeros(width), np.zeros(width), np.full(width, np.nan)
        self.low, self.high, self.peak = np.full(width, np.inf), np.full(width, -np.inf), np.zeros(width)
        self.count = 0

    def _real(self, rows):
        """The Real columns of rows of outputs (a String output's text never reaches float())."""
        if isinstance(rows, np.ndarray) and rows.dtype.kind == "f":          # a block's readings
            return rows[:, self.idx]
        return np.array([[row[i] for i in self.idx] for row in rows], dtype=float).reshape(len(rows), len(self.idx))

    def _take(self, ours, ref):
        """Rows (grid points x columns) of the run and of the reference at the same grid points."""
        if not len(ref):
            return
        with np.errstate(over="ignore", invalid="ignore"):
            ours, ref = self._real(ours), self._real(ref)
            d = np.abs(ours - ref)
            self.worst = np.maximum(self.worst, d.max(axis=0))     # a NaN stays NaN
            self.sumsq += np.sum(d * d, axis=0)
        self.final = d[-1]
        self.low, self.high = np.minimum(self.low, ref.min(axis=0)), np.maximum(self.high, ref.max(axis=0))
        self.peak = np.maximum(self.peak, np.abs(ref).max(axis=0))
        self.count += len(ref)

    def _one(self, outputs, k):
        ref = self.reference(k)
        if ref is not None:
            self._take([outputs], [ref])

    def start(self, first):
        self._one(first.outputs, 0)

    def after_step(self, n, t, log, reading, row):
        self._one(reading.outputs, n + 1)

    def after_block(self, n0, logs, readings, rows, at=None):
        ref = self.reference_rows(n0 + 1, len(rows))
        self._take(readings.outputs[:len(ref)], ref)

    def summary(self):
        if not self.count or not self.idx:
            return {}
        scale = column_scales(self.low, self.high, self.peak)
        worst, rms, final = self.worst / scale, np.sqrt(self.sumsq / self.count) / scale, self.final / scale
        errors = {"errors": dict(zip(self.names, worst.tolist()))}
        if not self.figures:
            return errors
        return {**errors, "max_error": float(np.max(worst)), "rms_error": float(np.max(rms)),
                "final_error": float(np.max(final))}


def error_observers(columns, types, error_names, reference, reference_rows=None):
    """The errors of a run against its reference: every Real output scaled by its range (ScaledErrors:
    `errors`), and the figures max_error, rms_error, final_error of the L2 norm over the scenario's
    `error` columns where it names some (ErrorTracker), else of the scaled columns."""
    scaled = ScaledErrors(columns, [category(kind) == REAL for kind in types], reference, reference_rows,
                          figures=not error_names)
    return [ErrorTracker(columns, error_names, reference, reference_rows), scaled] if error_names else [scaled]
