"""Every master over a grid of budgets on one scenario: accuracy, energy ledger and cost side by side.

Each run is measured against the monolithic reference (interface Newton). A run that fails
(non-finite values, an FMU error) is recorded with the rows it computed and marked not finite; a
finite run whose stored energy grew past DIVERGED_GROWTH times H(0) is marked diverged. Neither
stops the comparison.
"""
from pathlib import Path

import numpy as np

from .errors import RunFailed
from .masters import MASTERS
from .observers.recorder import write_json
from .runner import run
from .budget_sweep import reference_run

# Budgets K per master (each master class's `budgets`); None marks a master without an inner budget.
BUDGETS = {name: list(cls.budgets) for name, cls in MASTERS.items()}
DIVERGED_GROWTH = 1e3      # max H(t) / H(0) above this: the interface pumped energy in (no sources here)
COMPARE_FIELDS = ("master", "K", "finite", "diverged", "max_error", "rms_error", "final_error",
                  "max_interface_injection", "energy_drift", "H_growth", "iterations_mean", "doStep", "restore",
                  "wall_time_s", "real_time_factor")


def budgets_for(master, Ks=None):
    """The grid of K for one master: Ks when given and the master has a budget, else its default."""
    default = BUDGETS[master]
    return default if Ks is None or default == [None] else list(Ks)


def run_label(master, K):
    return master if K is None else f"{master}_K{K}"


def compare_row(result, K):
    """One line of the comparison: the run's summary plus its cost, energy growth and finiteness."""
    s = result.summary
    finite = result.status == "finished"                 # a run stops at its first non-finite value
    growth = s.get("H_growth", float("nan"))
    row = {"master": result.master, "K": "-" if K is None else K, "finite": "yes" if finite else "no",
           "diverged": ("n/a" if s["steps"] == 0 else                # failed before its first step
                        "no" if finite and not growth > DIVERGED_GROWTH else "yes"),
           "max_error": s.get("max_error", float("nan")), "rms_error": s.get("rms_error", float("nan")),
           "final_error": s.get("final_error", float("nan")), "H_growth": growth,
           "doStep": s["fmu_calls"]["doStep"], "save": s["fmu_calls"]["save"], "restore": s["fmu_calls"]["restore"]}
    row.update({k: v for k, v in s.items() if k not in row})
    return row


def compare(scenario, out_dir, masters=None, Ks=None, progress=None, certificates=True, on_run=None):
    """Run each master in `masters` over its budgets; writes DIR/compare.json after every run.

    Returns (reference, results, rows) with one result and row per (master, K)."""
    out_dir = Path(out_dir) if out_dir is not None else None
    masters = list(masters or BUDGETS)
    reference = reference_run(scenario, out_dir, progress and progress("monolithic"))
    results, rows = [], []
    for master in masters:
        for K in budgets_for(master, Ks):
            sc = scenario.with_master(algorithm=master, K=scenario.master.K if K is None else K)
            label = run_label(master, K)
            try:
                with np.errstate(all="ignore"):                  # a diverging master overflows; it is reported
                    result = run(sc, out_dir=out_dir, label=label, progress=progress and progress(label),
                                 certificates=certificates, reference=reference)
            except RunFailed as exc:
                result = exc.result
            results.append(result)
            rows.append(compare_row(result, K))
            if out_dir is not None:
                write_json(out_dir / "compare.json", {"scenario": scenario.name, "source": scenario.source,
                                                      "reference": reference.summary, "runs": rows})
            if on_run:
                on_run(rows[-1])
    return reference, results, rows
