"""Every master over a grid of budgets on one scenario: accuracy, energy ledger and cost side by side.

With `options` the DR master also runs with each of its named options (DR_OPTIONS); their rows
have master `dr` and the option's name in `option`. `cheapest` reads the rows back: for each
master (and option), the fewest doSteps per macro-step that reach a given max error.

Each run is measured against the monolithic reference (interface Newton). A run that fails
(non-finite values, outputs past the growth bound, an FMU error) is recorded with the rows it computed and marked not finite; a
finite run whose stored energy grew past DIVERGED_GROWTH times H(0) is marked diverged. Neither
stops the comparison.

A run is energy-safe (`energy_safe`, what `cheapest` asks of a row) when the interface never
supplied net energy: the largest cumulative interface supply max_n sum_{k<=n} I^k (`ledger_max`) is
within roundoff (a run with the energy ledger: within the ledger's own tolerance; otherwise
ledger.RTOL times the energy that went through the ports), and, where every subsystem's H is
known and no signal drives the scene, H never rose above H(0) by more than that. With signals (their
work is unknown) the ledger alone decides.
"""
from pathlib import Path

import numpy as np

from ..errors import ConfigError, RunFailed
from ..masters import MASTERS
from ..masters.ledger import RTOL
from ..run.recorder import write_json
from ..run.runner import run
from .budget import reference_run

# Budgets K per master (each master class's `budgets`); None marks a master without an inner budget.
BUDGETS = {name: list(cls.budgets) for name, cls in MASTERS.items()}
DIVERGED_GROWTH = 1e3      # max H(t) / H(0) above this: the interface pumped energy in (no sources here)
# The DR options compare can add: name -> (scenario gamma or None to keep the scenario's, master options,
# marker in the plots). Energy-safe all: the ledger guard (the DR default) holds every one; Theorem 1's
# per-step certificate holds for all but those with Anderson acceleration (masters/dr_options.py).
# fastest-memory's lambda = 1.9 was found by a grid over lambda on Table I and the stiff scene (docs/masters.md);
# -eps3 / -eps5 add the inner tolerance eps = 1e-3 / 1e-5 (the exit lowers the doSteps actually made).
DR_OPTIONS = {
    "relaxed": (None, {"relaxation": "auto"}, ("tab:cyan", "v")),
    "anderson": (None, {"anderson": 2}, ("navy", "^")),
    "warm": (None, {"start": "extrapolated"}, ("tab:gray", "<")),
    "gamma-auto": ("auto", {}, ("slateblue", ">")),
    "gamma-fastest": ("fastest", {}, ("teal", "d")),
    "fastest-relaxed": ("fastest", {"relaxation": "auto"}, ("tab:green", "*")),
    "fastest-relaxed-anderson": ("fastest", {"relaxation": "auto", "anderson": 2}, ("darkgreen", "h")),
    "fastest-relaxed-extrapolated": ("fastest", {"relaxation": "auto", "anderson": 2, "anderson_extrapolate": True},
                                     ("tab:brown", "8")),
    "fastest-relaxed-memory": ("fastest", {"relaxation": "auto", "anderson": 4, "anderson_memory": True,
                                           "anderson_extrapolate": True}, ("maroon", "p")),
    "fastest-memory": ("fastest", {"relaxation": 1.9, "anderson": 4, "anderson_memory": True,
                                   "anderson_extrapolate": True}, ("olive", "P")),
    "fastest-memory-eps3": ("fastest", {"relaxation": 1.9, "anderson": 4, "anderson_memory": True,
                                        "anderson_extrapolate": True, "eps": 1e-3}, ("yellowgreen", "P")),
    "fastest-memory-eps5": ("fastest", {"relaxation": 1.9, "anderson": 4, "anderson_memory": True,
                                        "anderson_extrapolate": True, "eps": 1e-5}, ("darkolivegreen", "P")),
    # options: auto chooses gamma, lambda and the Anderson window from the scene; -epsN adds the inner
    # tolerance 1e-N, a decade below each target error (3, 6, 10)
    "auto": (None, {"options": "auto"}, ("crimson", "X")),
    "auto-eps4": (None, {"options": "auto", "eps": 1e-4}, ("orangered", "X")),
    "auto-eps7": (None, {"options": "auto", "eps": 1e-7}, ("darkred", "X")),
    "auto-eps11": (None, {"options": "auto", "eps": 1e-11}, ("lightcoral", "X")),
}
CERTIFIED = ("", "relaxed", "warm", "gamma-auto", "gamma-fastest", "fastest-relaxed")   # Theorem 1 applies
TARGETS = (1e-3, 1e-6, 1e-10)      # max errors the cheapest budget is sought for
COMPARE_FIELDS = ("master", "option", "K", "finite", "diverged", "energy_safe", "max_error", "rms_error",
                  "final_error", "ledger_max", "energy_allowance", "max_interface_injection", "energy_drift", "H_growth",
                  "iterations_mean", "doStep", "doSteps_per_step", "critical_path_doSteps", "restore", "wall_time_s",
                  "real_time_factor")


def parse_options(names):
    """DR option names from a list or a comma-separated string ("all": every one); ConfigError names a bad one."""
    if isinstance(names, str):
        names = list(DR_OPTIONS) if names.strip() == "all" else [n.strip() for n in names.split(",") if n.strip()]
    for name in names:
        if name not in DR_OPTIONS:
            raise ConfigError(f"--options: unknown DR option {name!r} (have: {', '.join(DR_OPTIONS)}, all)")
    return list(names)


def budgets_for(master, Ks=None):
    """The grid of K for one master: Ks when given and the master has a budget, else its default."""
    default = BUDGETS[master]
    return default if Ks is None or default == [None] else list(Ks)


def group_name(row):
    """The name of a row's master and option: `dr`, `dr:relaxed`, `gauss-seidel-iter`."""
    return f"{row['master']}:{row['option']}" if row.get("option") else row["master"]


def style(name):
    """(colour, marker) of a master or master:option in the plots."""
    master, _, option = name.partition(":")
    if option in DR_OPTIONS:
        return DR_OPTIONS[option][2]
    return MASTERS[master].style if master in MASTERS else ("gray", "o")


def run_label(master, K, option=""):
    name = folder_name(master, option)
    return name if K is None else f"{name}_K{K}"


def folder_name(master, option=""):
    """The folder of a master's (or a DR option's) runs under compare's output folder: `dr`, `dr-relaxed`."""
    return f"{master}-{option}" if option else master


def column(result, name):
    """A per-step column of a run (None when the run has none)."""
    table = result.steps_table
    if table is None or name not in table.columns:
        return None
    return table.array()[:, table.columns.index(name)]


def energy_safety(result):
    """(safe, ledger_max, allowance) of a run (module docstring): the largest cumulative interface
    supply, and whether it and the stored energy stayed within roundoff."""
    s, supply = result.summary, column(result, "interface_supply")
    if supply is None or not len(supply):
        return False, float("nan"), float("nan")
    ledger_max = float(np.max(np.cumsum(supply)))
    if "ledger_tolerance" in s:                                 # the ledger's own tolerance
        tol = s["ledger_tolerance"]
        return ledger_max <= tol and _H_within(result, tol), ledger_max, tol
    ports = [column(result, c) for c in result.steps_table.columns if c.startswith("port_energy_")
             and not c.startswith("port_energy_cum_")]
    if "H_initial" in s:
        scale = len(supply) * max(abs(s["H_initial"]), abs(s["H_initial"] * s.get("H_growth", 1.0)))
    else:
        scale = float(sum(np.abs(p).sum() for p in ports)) or float(np.abs(supply).sum())
    allowance = RTOL * scale
    return ledger_max <= allowance and _H_within(result, allowance), ledger_max, allowance


def _H_within(result, allowance):
    """H never rose above H(0) + allowance, where every H is known and no signal drives the scene."""
    s = result.summary
    if "H_initial" not in s or s.get("signals"):
        return True
    H = np.asarray(result.energy, float)
    scale = RTOL * len(H) * max(abs(s["H_initial"]), 1e-300)
    return bool(np.all(np.isfinite(H))) and float(H.max()) <= s["H_initial"] + max(allowance, scale)


def compare_row(result, K, option="", subsystems=1):
    """One line of the comparison: the run's summary plus its cost, energy safety and finiteness.
    critical_path_doSteps: doSteps per macro-step that cannot run side by side (a sequential master's
    all, a parallel one's divided among its `subsystems`, each making the same calls)."""
    s = result.summary
    finite = result.status in ("finished", "suspect")    # a run stops at its first non-finite value
    growth = s.get("H_growth", float("nan"))
    safe, ledger_max, allowance = energy_safety(result) if s["steps"] else (False, float("nan"), float("nan"))
    per_step = s["fmu_calls"]["doStep"] / max(s["steps"], 1)
    sequential = getattr(MASTERS.get(result.master), "sequential", False)
    row = {"master": result.master, "option": option, "K": "-" if K is None else K,
           "finite": "yes" if finite else "no",
           "diverged": ("n/a" if s["steps"] == 0 else                # failed before its first step
                        "no" if finite and not growth > DIVERGED_GROWTH else "yes"),
           "energy_safe": "yes" if finite and safe else "no", "ledger_max": ledger_max, "energy_allowance": allowance,
           "max_error": s.get("max_error", float("nan")), "rms_error": s.get("rms_error", float("nan")),
           "final_error": s.get("final_error", float("nan")), "H_growth": growth,
           "doStep": s["fmu_calls"]["doStep"], "save": s["fmu_calls"]["save"], "restore": s["fmu_calls"]["restore"],
           "doSteps_per_step": per_step, "critical_path_doSteps": per_step if sequential else per_step / subsystems}
    row.update({k: v for k, v in s.items() if k not in row})
    return row


def _runs(scenario, masters, Ks, options):
    """(master, option, K, scenario) of every run: each master over its budgets, then DR per option."""
    for master in masters:
        for K in budgets_for(master, Ks):
            yield master, "", K, scenario.with_master(algorithm=master, K=scenario.master.K if K is None else K)
    for option in options if "dr" in masters else ():
        gamma, changes, _ = DR_OPTIONS[option]
        sc = scenario if gamma is None else scenario.with_changes(gamma=gamma)
        for K in budgets_for("dr", Ks):
            yield "dr", option, K, sc.with_master(algorithm="dr", K=K, **changes)


def _one_run(sc, out_dir, label, progress, certificates, reference):
    """One run of the comparison; a run that fails is its partial result."""
    try:
        with np.errstate(all="ignore"):                  # a diverging master overflows; it is reported
            return run(sc, out_dir=out_dir, label=label, progress=progress and progress(label),
                       certificates=certificates, reference=reference)
    except RunFailed as exc:
        return exc.result


def compare(scenario, out_dir, masters=None, Ks=None, progress=None, certificates=True, on_run=None, options=()):
    """Run each master in `masters` over its budgets, and DR with each of `options` (names of
    DR_OPTIONS); writes DIR/compare.json after every run, and each run's files into the folder of its
    master (DIR/dr/, DIR/dr-relaxed/, DIR/monolithic/ for the reference). Returns (reference, results, rows)."""
    out_dir = Path(out_dir) if out_dir is not None else None
    within = (lambda name: out_dir / name) if out_dir is not None else (lambda name: None)
    masters = list(masters or BUDGETS)
    reference = reference_run(scenario, within("monolithic"), progress and progress("monolithic"))
    results, rows = [], []
    for master, option, K, sc in _runs(scenario, masters, Ks, options):
        result = _one_run(sc, within(folder_name(master, option)), run_label(master, K, option), progress,
                          certificates, reference)
        results.append(result)
        rows.append(compare_row(result, K, option, len(scenario.subsystems)))
        if out_dir is not None:
            write_json(out_dir / "compare.json", {"scenario": scenario.name, "source": scenario.source,
                                                  "reference": reference.summary, "runs": rows,
                                                  "cheapest": cheapest(rows),
                                                  "cheapest_any_energy": cheapest(rows, safe=False)})
        if on_run:
            on_run(rows[-1])
    return reference, results, rows


def cheapest(rows, targets=TARGETS, safe=True):
    """{target: {master or master:option: the row with the fewest doSteps per macro-step whose max error
    is at most target (and, with `safe`, energy-safe; else only finite)}}, as (K, doSteps_per_step,
    critical_path_doSteps, max_error, wall_time_s)."""
    out = {}
    for target in targets:
        best = {}
        for r in rows:
            name = group_name(r)
            if r.get("energy_safe" if safe else "finite") != "yes" or not r["max_error"] <= target:
                continue
            if name not in best or r["doSteps_per_step"] < best[name]["doSteps_per_step"]:
                best[name] = {k: r.get(k) for k in ("K", "doSteps_per_step", "critical_path_doSteps", "max_error",
                                                    "wall_time_s")}
        out[f"{target:g}"] = best
    return out
