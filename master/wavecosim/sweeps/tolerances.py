"""`compare --tolerances`: what should I run? The tolerance mode at each tolerance (each master's
predictor estimate, and the step doubling baseline) beside a grid of fixed (dt, K) of a few masters,
every run's true error against one fine reference, its FMU calls and its wall time: a table
(tolerances.csv, tolerances.json) and a figure (tolerances.png)."""
import csv
import json
import math
import time

from ..errors import WavecosimError
from ..run.fine import FINE_STEPS, true_error
from ..run.runner import reference_scenario, run

TOLERANCE_MASTERS = ("dr", "gauss-seidel")          # the tolerance mode's masters by default
FIXED = (("explicit", None), ("gauss-seidel", None), ("dr", 5), ("dr", 20), ("newton", None))
REFINE = (1, 4, 16)                                 # the fixed grid's steps: dt / each
FIELDS = ("mode", "master", "K", "tolerance", "dt", "true_error", "doStep", "save", "restore", "wall_time_s",
          "accepted_steps", "rejected_steps", "status")
MAX_STEPS = 2_000_000                               # a fixed run of more steps is left out of the grid


def fine(scenario):
    """The reference every run is measured against: the monolithic master at span / FINE_STEPS."""
    span = scenario.T - scenario.start_time
    sc = reference_scenario(scenario).with_master(tolerance=None).with_changes("the fine reference",
                                                                               dt=span / FINE_STEPS)
    return run(sc, None, label="fine", certificates=False, warn=lambda message: None, max_steps=None)


def plan(scenario, tolerances, masters=TOLERANCE_MASTERS):
    """(mode, scenario) of every run: the tolerance mode per master and tolerance, doubling with the
    first master, then the fixed grid."""
    out = []
    for tol in tolerances:
        for m in masters:
            out.append(("tolerance", scenario.with_master(algorithm=m, tolerance=tol, estimate="predictor")))
        out.append(("doubling", scenario.with_master(algorithm=masters[0], tolerance=tol, estimate="doubling")))
    for m, K in FIXED:
        for r in REFINE:
            dt = scenario.dt / r
            if (scenario.T - scenario.start_time) / dt <= MAX_STEPS:
                changes = {"algorithm": m, "tolerance": None, **({"K": K} if K is not None else {})}
                out.append(("fixed", scenario.with_master(**changes).with_changes("the fixed grid", dt=dt)))
    return out


def measure(mode, sc, reference):
    """One run and its row."""
    started = time.perf_counter()
    row = {"mode": mode, "master": sc.master.algorithm, "K": sc.master.K if sc.master.algorithm == "dr" else "",
           "tolerance": sc.master.tolerance or "", "dt": sc.dt}
    try:
        result = run(sc, None, label=mode, certificates=False, warn=lambda message: None, max_steps=None)
    except WavecosimError as exc:
        return {**row, "status": f"{exc.status}: {exc}", "true_error": math.nan}
    s = result.summary
    return {**row, "true_error": true_error(result, reference)["true_error"], **s["fmu_calls"],
            "wall_time_s": time.perf_counter() - started, "accepted_steps": s.get("accepted_steps", s["steps"]),
            "rejected_steps": s.get("rejected_steps", 0), "status": s["status"]}


def compare_tolerances(scenario, tolerances, out_dir=None, masters=TOLERANCE_MASTERS, progress=None):
    """Every run of plan() against one fine reference; the rows (and the files in out_dir)."""
    reference = fine(scenario)
    rows = []
    for mode, sc in plan(scenario, tolerances, masters):
        rows.append(measure(mode, sc, reference))
        if progress:
            progress(rows[-1])
    if out_dir is not None:
        write(rows, out_dir)
    return rows


def write(rows, out_dir):
    """tolerances.csv and tolerances.json."""
    with open(out_dir / "tolerances.csv", "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS, restval="", extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    (out_dir / "tolerances.json").write_text(json.dumps(rows, indent=1))


def best_fixed(rows, target):
    """The fixed run with the fewest doSteps whose true error is at most `target` (None: none reaches it)."""
    ok = [r for r in rows if r["mode"] == "fixed" and r["true_error"] <= target]
    return min(ok, key=lambda r: r["doStep"], default=None)
