"""Error against the monolithic reference, computed as the run streams: per grid point
||(dq1, dq2, ...)||_2 over the scenario's error columns, and its max, time-RMS and final value."""
import math

import numpy as np

from . import Observer


class ErrorTracker(Observer):
    """Column `error`; `reference(k)` gives the reference's outputs at grid point k (None: no more)."""
    columns = ("error",)

    def __init__(self, output_names, error_names, reference):
        self.idx = [output_names.index(c) for c in error_names]
        self.reference = reference
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

    def summary(self):
        if not self.count:
            return {}
        return {"max_error": self.max, "rms_error": math.sqrt(self.sumsq / self.count), "final_error": self.final}


def stored_reference(result):
    """reference(k) from a finished RunResult's trajectory (all its output columns)."""
    outputs = result.outputs
    return lambda k: outputs[k] if k < len(outputs) else None


def error_metrics(result, reference, columns):
    """The same figures after the fact, from two finished results: (error per grid point, metrics)."""
    n = min(len(result.t), len(reference.t))
    diff = np.stack([result.column(c)[:n] - reference.column(c)[:n] for c in columns], axis=1)
    err = np.sqrt(np.sum(diff * diff, axis=1))
    return err, {"max_error": float(err.max()), "rms_error": float(np.sqrt(np.mean(err * err))),
                 "final_error": float(err[-1])}
