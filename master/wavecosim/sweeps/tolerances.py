"""`compare --tolerances`: what should I run? The tolerance mode at each tolerance (each master's
predictor estimate, and the step doubling baseline) beside a grid of fixed (dt, K) of a few masters,
every run's true error against one fine reference, its FMU calls and its wall time: a table
(tolerances.csv, tolerances.json) and a figure (tolerances.png)."""
import csv
import json
import math
import time

from ..errors import Interrupted, WavecosimError
from ..masters.adaptive import fmu_tolerance_cap
from ..run.fine import FINE_STEPS, fine_reference, true_error
from ..run.runner import run
from ..scenario.config import SIGNALS_MASTER
from .ecco import peer_rows

TOLERANCE_MASTERS = ("dr", "gauss-seidel")          # the tolerance mode's masters by default
FIXED = (("explicit", None), ("gauss-seidel", None), ("dr", 5), ("dr", 20), ("newton", None))
SIGNALS_ONLY = (SIGNALS_MASTER,)                    # the one master of a system without power bonds
REFINE = (1, 4, 16)                                 # the fixed grid's steps: dt / each
FIELDS = ("mode", "master", "K", "tolerance", "dt", "true_error", "doStep", "save", "restore", "wall_time_s",
          "accepted_steps", "rejected_steps", "max_ledger", "ledger_tolerance", "status")
MAX_STEPS = 2_000_000                               # a fixed run of more steps is left out of the grid
MAX_ORDER = 2                                       # the highest order in h of any master's error


def fine(scenario):
    """The reference every run is measured against: the monolithic master at span / FINE_STEPS
    (Richardson's extrapolation with half that step where its error is first order: run/fine.py)."""
    return fine_reference(scenario, None, dt=(scenario.T - scenario.start_time) / FINE_STEPS)


def fixed_fmus(scenario, tolerances):
    """The scenario with its FMUs set up as the tightest tolerance run sets up its own (master.fmu_tolerance):
    the fixed grid and the reference, so that no fixed run is held back by its FMUs' error."""
    return scenario.with_master(fmu_tolerance=fmu_tolerance_cap(scenario.with_master(tolerance=min(tolerances)).master))


def default_masters(scenario):
    """The tolerance mode's masters when none are named: TOLERANCE_MASTERS, or the explicit master
    alone on a system of signals only."""
    return TOLERANCE_MASTERS if scenario.couplings else SIGNALS_ONLY


def plan(scenario, tolerances, masters=None, refine=REFINE):
    """(mode, scenario) of every run: the tolerance mode per master (default_masters) and tolerance,
    doubling with the first master, then the fixed grid (dt / each of `refine`, its FMUs as
    fixed_fmus sets them up; the explicit master alone without power bonds)."""
    masters = masters or default_masters(scenario)
    out = []
    for tol in tolerances:
        for m in masters:
            out.append(("tolerance", scenario.with_master(algorithm=m, tolerance=tol, estimate="auto")))
        out.append(("doubling", scenario.with_master(algorithm=masters[0], tolerance=tol, estimate="doubling")))
    for m, K in FIXED if scenario.couplings else [(m, None) for m in SIGNALS_ONLY]:
        for r in refine:
            dt = scenario.dt / r
            if (scenario.T - scenario.start_time) / dt <= MAX_STEPS:
                changes = {"algorithm": m, "tolerance": None, **({"K": K} if K is not None else {})}
                out.append(("fixed", fixed_fmus(scenario, tolerances).with_master(**changes)
                             .with_changes("the fixed grid", dt=dt)))
    return out


def measure(mode, sc, reference):
    """One run and its row; Ctrl-C or SIGTERM ends the comparison."""
    started = time.perf_counter()
    row = {"mode": mode, "master": sc.master.algorithm, "K": sc.master.K if sc.master.algorithm == "dr" else "",
           "tolerance": sc.master.tolerance or "", "dt": sc.dt}
    try:
        result = run(sc, None, label=mode, certificates=False, warn=lambda message: None, max_steps=None)
    except Interrupted:
        raise
    except WavecosimError as exc:                 # a run that failed is a row saying so
        return {**row, "status": f"{exc.status}: {exc}", "true_error": math.nan}
    s = result.summary
    return {**row, "true_error": true_error(result, reference)["true_error"], **s["fmu_calls"],
            "wall_time_s": time.perf_counter() - started, "accepted_steps": s.get("accepted_steps", s["steps"]),
            "rejected_steps": s.get("rejected_steps", 0), "max_ledger": s.get("max_ledger", ""),
            "ledger_tolerance": s.get("ledger_tolerance", ""), "status": s["status"]}


def compare_tolerances(scenario, tolerances, out_dir=None, masters=None, progress=None, peers=(),
                       note=None, refine=REFINE):
    """Every run of plan() against one fine reference, then the peers' (sweeps/ecco.py: PEERS) at each
    tolerance; the rows (and the files in out_dir). `note` takes the line of a peer left out."""
    reference = fine(fixed_fmus(scenario, tolerances))
    rows = []
    for mode, sc in plan(scenario, tolerances, masters, refine):
        rows.append(measure(mode, sc, reference))
        if progress:
            progress(rows[-1])
    rows += peer_rows(scenario, tolerances, reference, peers, progress, note)
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


def calls_for(points, target):
    """The doSteps a fixed series [(doSteps, true error)] needs for a true error of `target`: its
    cheapest run already that accurate, else along the log-log line through the two runs around the
    target (past its most accurate run, the line through its last two, no steeper than order
    MAX_ORDER: a series that was far from converged does not promise more): (doSteps, extrapolated)."""
    points = sorted(p for p in points if p[1] > 0 and math.isfinite(p[1]))
    first = next((p for p in points if p[1] <= target), None)
    if first is not None and first is points[0]:
        return float(first[0]), False
    pairs = [(a, b) for a, b in zip(points, points[1:]) if b[1] < a[1]]
    if not pairs:
        return math.nan, True
    a, b = next(((a, b) for a, b in pairs if b[1] <= target), pairs[-1])
    slope = math.log(b[0] / a[0]) / math.log(b[1] / a[1])
    if first is None:                    # past the most accurate run b: at most the highest order of a master
        return b[0] * (target / b[1]) ** min(slope, -1.0 / MAX_ORDER), True
    return a[0] * (target / a[1]) ** slope, False


def best_fixed(rows, target):
    """The fixed (master, K) needing the fewest doSteps for a true error of `target` (calls_for):
    (doSteps, extrapolated, "master K=k"), or None."""
    series = {}
    for r in rows:
        if r["mode"] == "fixed" and math.isfinite(r["true_error"]):
            key = r["master"] + (f" K={r['K']}" if r["K"] != "" else "")
            series.setdefault(key, []).append((r["doStep"], r["true_error"]))
    found = [(*calls_for(points, target), key) for key, points in series.items()]
    return min((f for f in found if math.isfinite(f[0])), key=lambda f: f[0], default=None)
