"""`wavecosim bench`, parallel_threads rows: DR on eight heavy subsystems, 1, 2, 4 and 8 threads.

On configs/heavy_chain_8.yaml (eight 100-mass chains on one cable, a few hundred µs per doStep each),
the fast-path master alone (no recording) makes the macro-steps in blocks with `master.threads: N`;
each row is the best µs per macro-step over the repeats, taken in rounds over every N so that a busy
spell of the machine hits all rows alike. Beside it: the ideal of that plan (K + 1 rounds of its
busiest thread, from the costs the kernel timed) and the floor of any plan (K + 1 rounds of the
costliest subsystem). N above the CPUs runs min(N, CPUs) threads (`threads_used`). The target:
speedup >= 0.8 x min(N, CPUs) over N = 1 when every subsystem step costs >= 200 µs.
"""
import dataclasses
import os
import statistics

from .common import master_seconds
from ..examples import path as example
from ..kernel.drkernel import available_cpus, thread_plan
from ..masters.dr_fast import FastDRMaster
from ..scenario.config import load_scenario
from ..core.scene import build_scene

HEAVY_8 = example("heavy_chain_8")
THREADS = (1, 2, 4, 8)
TARGET_SHARE = 0.8         # speedup >= this x min(threads, CPUs) ...
TARGET_MIN_US = 200.0      # ... where every subsystem step costs at least this


def _one(scenario, threads, n_steps):
    """(seconds of macro-steps 1 .. n_steps - 1, threads used, µs per evaluation timed or None)."""
    scene = build_scene(scenario)
    settings = dataclasses.replace(scenario.master, eps=None, deadline_us=None, fast="true", threads=str(threads))
    master = FastDRMaster(scene, settings)
    try:
        seconds = master_seconds(master, n_steps, scenario.dt, blocks=True)
        return seconds, master.planner.threads, master.planner.costs
    finally:
        master.close()
        scene.close()


def parallel_threads(quick=False, progress=print):
    """The rows {threads, threads_used, us_per_step, speedup, ideal_us_per_step} and the figures beside them."""
    scenario = load_scenario(HEAVY_8)
    n_steps, repeats = (12, 2) if quick else (40, 3)
    best, used, costs = dict.fromkeys(THREADS, float("inf")), {}, []
    load_before = os.getloadavg()
    for r in range(repeats):
        progress(f"  eight heavy chains, threads {'/'.join(map(str, THREADS))}: repeat {r + 1}/{repeats}")
        for threads in THREADS:
            seconds, used[threads], timed = _one(scenario, threads, n_steps)
            best[threads] = min(best[threads], 1e6 * seconds / (n_steps - 1))
            if timed:
                costs.append(timed)
    cost = [statistics.median(c[i] for c in costs) for i in range(len(costs[0]))]
    rounds, cpus = scenario.master.K + 1, available_cpus()
    rows = []
    for threads in THREADS:
        speedup = best[1] / best[threads]
        rows.append({"threads": threads, "threads_used": used[threads], "us_per_step": best[threads],
                     "speedup": speedup, "ideal_us_per_step": rounds * max(thread_plan(cost, used[threads])[1]),
                     "target_speedup": TARGET_SHARE * min(threads, cpus)})
    heavy = min(cost) >= TARGET_MIN_US
    return {"scene": scenario.name, "K": scenario.master.K, "steps": n_steps, "repeats": repeats,
            "subsystems": len(cost), "us_per_eval": cost, "cpus": cpus,
            "floor_us_per_step": rounds * max(cost), "rows": rows,
            "load_average_1min": [load_before[0], os.getloadavg()[0]],
            "target_applies": heavy,
            "target_met": heavy and all(r["speedup"] >= r["target_speedup"] for r in rows)}


def report_threads(p):
    """Printed lines of the parallel_threads rows."""
    lines = [f"{p['scene']}: DR K = {p['K']}, {p['subsystems']} subsystems of "
             f"{min(p['us_per_eval']):.0f}-{max(p['us_per_eval']):.0f} µs per evaluation, {p['cpus']} CPUs, "
             f"load average {p['load_average_1min'][0]:.2f} -> {p['load_average_1min'][1]:.2f}; "
             f"floor (costliest subsystem per round) {p['floor_us_per_step']:.0f} µs per step",
             f"{'threads':>8}{'used':>6}{'µs/step':>11}{'speedup':>9}{'target':>8}{'ideal µs/step':>15}"]
    for r in p["rows"]:
        lines.append(f"{r['threads']:>8}{r['threads_used']:>6}{r['us_per_step']:>11.0f}{r['speedup']:>9.2f}"
                     f"{r['target_speedup']:>8.2f}{r['ideal_us_per_step']:>15.0f}")
    return lines
