"""`wavecosim bench`, classical rows: the fixed-point masters on the kernel route against their
Python loops (the same numbers, tests/masters/test_routes.py).

On Table I, for explicit and gauss-seidel, and jacobi-iter and gauss-seidel-iter at K = 1, 3, 10:
master seconds of macro-steps 1 .. steps - 1 from a fresh scene (physical port mode), the best of
a few repeats, three ways: `master.fast: false` (the Python reference), the kernel
(kernel/c/classical.c) one call per macro-step (step), and the kernel making blocks of
macro-steps per call (run_steps), as the runner drives it. The speedup is Python over blocks; the
target (>= 10x) holds for every master and budget.
"""
import dataclasses

from .common import master_seconds
from ..masters import MASTERS
from ..core.scene import build_scene

KS = (1, 3, 10)
CLASSICAL = {"explicit": (0,), "gauss-seidel": (0,), "jacobi-iter": KS, "gauss-seidel-iter": KS}   # budgets timed
TARGET_SPEEDUP = 10.0


ROUTES = {"python_s": ("false", False), "kernel_step_s": ("true", False), "kernel_s": ("true", True)}


def _seconds(scenario, name, K, route, steps):
    fast, blocks = ROUTES[route]
    scene = build_scene(scenario, wave=False)
    master = MASTERS[name](scene, dataclasses.replace(scenario.master, algorithm=name, K=K, eps=None,
                                                      deadline_us=None, fast=fast, energy_guard="off"))
    try:
        return master_seconds(master, steps, scenario.dt, blocks)
    finally:
        master.close()
        scene.close()


def classical_rows(scenario, quick=False, progress=print):
    """{master: {K: {"python_s", "kernel_step_s", "kernel_s", "speedup"}}} and the smallest speedup (JSON-ready)."""
    steps, repeats = (200, 2) if quick else (1000, 3)
    rows = {}
    for name, budgets in CLASSICAL.items():
        progress(f"  {name}: Python loop against the kernel route")
        rows[name] = {}
        for K in budgets:
            best = dict.fromkeys(ROUTES, float("inf"))
            for _ in range(repeats):
                for route in best:
                    best[route] = min(best[route], _seconds(scenario, name, K, route, steps))
            rows[name][str(K)] = {**best, "speedup": best["python_s"] / best["kernel_s"]}
    speedup = min(r["speedup"] for by_K in rows.values() for r in by_K.values())
    return {"scene": scenario.name, "steps": steps, "masters": rows, "speedup_min": speedup,
            "target_met": speedup >= TARGET_SPEEDUP}


def report_classical(c):
    """Printed lines of the classical rows."""
    lines = [f"classical masters, {c['scene']}, {c['steps']} steps: master s Python / kernel per step / "
             f"kernel in blocks (speedup of blocks)"]
    for name, by_K in c["masters"].items():
        cells = [(f"K={K}: " if len(by_K) > 1 else "") + f"{r['python_s']:.3f} / {r['kernel_step_s']:.4f} / "
                 f"{r['kernel_s']:.4f} ({r['speedup']:.1f}x)" for K, r in by_K.items()]
        lines.append(f"  {name:<18}" + "   ".join(cells))
    return lines
