"""The error against the true solution: the monolithic reference (the `newton` master) run at a
refined step, FINE times finer than the run's typical step (the smaller of dt and the median of the
accepted steps; at most FINE_STEPS steps), each output column interpolated onto the run's accepted
times and its error scaled by the column's range. Where the reference's own error is first order in
its step (an input held over the step: a signal, the wave adapter), it is run again at half the step
and the two are combined by Richardson's extrapolation, 2 x_(h/2) - x_h, which is second order. Its
FMUs are set up as the run's (master.fmu_tolerance)."""
import math
from dataclasses import dataclass

import numpy as np

from ..masters.adaptive import fmu_tolerance_cap
from .runner import reference_scenario, run

FINE = 16                   # the reference's step: the run's typical step / FINE
FINE_STEPS = 200_000        # at most this many reference steps (the step is then the span / FINE_STEPS)


def fine_dt(scenario, result):
    """The reference's step: a whole fraction of the span, FINE times below the run's typical step."""
    t = result.t
    typical = min(float(np.median(np.diff(t))), scenario.dt) if len(t) > 1 else scenario.dt
    span = scenario.T - scenario.start_time
    steps = min(FINE_STEPS, math.ceil(FINE * span / typical - 1e-9))
    return span / steps


@dataclass
class Extrapolated:
    """Richardson's extrapolation of two reference runs at h and h/2 on the coarser run's times: what
    true_error and the peers read of a reference (t, columns, error_columns, column)."""
    t: np.ndarray
    values: dict
    error_columns: list
    dt: float
    summary: dict

    @property
    def columns(self):
        return list(self.values)

    def column(self, name):
        return self.values[name]


def richardson(coarse, half):
    """2 x_(h/2) - x_h at the coarse run's times (each also a time of the half-step run)."""
    t, t_half = coarse.t, half.t
    values = {c: 2.0 * np.interp(t, t_half, half.column(c)) - coarse.column(c) for c in coarse.columns
              if c in half.columns}
    return Extrapolated(coarse.t, values, coarse.error_columns, float(coarse.t[1] - coarse.t[0]),
                        coarse.summary)


def fine_reference(scenario, result, dt=None):
    """The monolithic reference of `result`'s scenario at a refined step (fine_dt): a RunResult, or
    its Richardson extrapolation with a run at half the step where its error is first order."""
    fine = reference_scenario(scenario).with_master(tolerance=None, fmu_tolerance=fmu_tolerance_cap(scenario.master))
    fine = fine.with_changes("the fine reference", dt=dt or fine_dt(scenario, result))
    coarse = _run(fine)
    if coarse.summary.get("error_order", 2) >= 2 or coarse.status != "finished" or len(coarse.t) < 2:
        return coarse
    half = _run(fine.with_changes("the fine reference", dt=fine.dt / 2.0))
    return richardson(coarse, half) if half.status == "finished" else coarse


def _run(scenario):
    """One reference run, quietly and without certificates."""
    return run(scenario, None, label="fine", reference=None, certificates=False, warn=lambda message: None,
               max_steps=None)


def true_error(result, reference, columns=None):
    """{"true_error": the largest over `columns` (default: the scenario's error columns, else every
    numeric one) of max over time |x - x_ref| / range(x_ref), "true_error_by_column": each}."""
    columns = [c for c in (columns or result.error_columns or result.columns) if c in reference.columns]
    t, t_ref = result.t, reference.t
    by = {}
    for c in columns:
        ref = reference.column(c)
        span = float(np.max(ref) - np.min(ref))
        diff = np.abs(result.column(c) - np.interp(t, t_ref, ref))
        by[c] = float(np.max(diff) / span) if span > 0 else float(np.max(diff))
    return {"true_error": max(by.values(), default=math.nan), "true_error_by_column": by,
            "true_reference_dt": float(t_ref[1] - t_ref[0]) if len(t_ref) > 1 else math.nan,
            "true_reference_richardson": isinstance(reference, Extrapolated)}
