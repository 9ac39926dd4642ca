"""`wavecosim bench`, classical rows: the fixed-point masters on the kernel route against their
Python loops (the same numbers, tests/test_classical_kernel.py).

On Table I, for explicit and gauss-seidel, and jacobi-iter and gauss-seidel-iter at K = 1, 3, 10:
master seconds of macro-steps 1 .. steps - 1 from a fresh scene (physical port mode),
`master.fast: false` (the Python reference) and `auto` (fmus/kernel/classical.c, one call per
macro-step), the best of a few repeats. The target (>= 10x) is judged at K = 10, where the inner
loop dominates; at small K the Python side of one kernel call per macro-step does.
"""
import dataclasses

from .bench import master_seconds
from .masters import MASTERS
from .scene import build_scene

KS = (1, 3, 10)
CLASSICAL = {"explicit": (0,), "gauss-seidel": (0,), "jacobi-iter": KS, "gauss-seidel-iter": KS}   # budgets timed
TARGET_SPEEDUP = 10.0


def _seconds(scenario, name, K, fast, steps):
    scene = build_scene(scenario, wave=False)
    master = MASTERS[name](scene, dataclasses.replace(scenario.master, algorithm=name, K=K, eps=None,
                                                      deadline_us=None, fast=fast, energy_guard="off"))
    try:
        return master_seconds(master, steps, scenario.dt)
    finally:
        master.close()
        scene.close()


def classical_rows(scenario, quick=False, progress=print):
    """{master: {K: {"python_s", "kernel_s", "speedup"}}} and the smallest speedup (JSON-ready)."""
    steps, repeats = (200, 2) if quick else (1000, 3)
    rows = {}
    for name, budgets in CLASSICAL.items():
        progress(f"  {name}: Python loop against the kernel route")
        rows[name] = {}
        for K in budgets:
            best = {"false": float("inf"), "auto": float("inf")}
            for _ in range(repeats):
                for fast in best:
                    best[fast] = min(best[fast], _seconds(scenario, name, K, fast, steps))
            rows[name][str(K)] = {"python_s": best["false"], "kernel_s": best["auto"],
                                  "speedup": best["false"] / best["auto"]}
    speedups = [r["speedup"] for by_K in rows.values() for r in by_K.values()]
    at_K10 = min(by_K["10"]["speedup"] for by_K in rows.values() if "10" in by_K)
    return {"scene": scenario.name, "steps": steps, "masters": rows, "speedup_min": min(speedups),
            "speedup_at_K10_min": at_K10, "target_met": at_K10 >= TARGET_SPEEDUP}


def report_classical(c):
    """Printed lines of the classical rows."""
    lines = [f"classical masters, {c['scene']}, {c['steps']} steps: master s Python / kernel (speedup)"]
    for name, by_K in c["masters"].items():
        cells = [(f"K={K}: " if len(by_K) > 1 else "") + f"{r['python_s']:.3f} / {r['kernel_s']:.4f} ({r['speedup']:.1f}x)"
                 for K, r in by_K.items()]
        lines.append(f"  {name:<18}" + "   ".join(cells))
    return lines
