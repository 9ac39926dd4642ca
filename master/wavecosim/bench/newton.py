"""`wavecosim bench`, newton rows: the newton master on the kernel route against its Python loop
(the same numbers, tests/masters/test_routes.py).

On Table I and the stiff scene (k12 = 12000): master seconds of macro-steps 1 .. steps - 1 from a
fresh scene (wave port mode), `master.fast: false` (the Python reference, wavecosim/masters/monolithic.py)
and `auto` (kernel/c/newton.c, one call per macro-step), the best of a few repeats; and the
doSteps per macro-step (the interface Newton's S-evaluations and the commit, per subsystem).
"""
import dataclasses

from .common import TABLE_I, master_seconds
from ..examples import path as example
from ..scenario.config import load_scenario
from ..masters import MASTERS
from ..core.scene import build_scene

SCENES = {"Table I": TABLE_I, "stiff": example("two_oscillators_stiff")}
TARGET_SPEEDUP = 10.0
TARGET = "newton on the kernel >= 10x faster than its Python loop"


def _seconds(scenario, fast, steps):
    """(master seconds, doSteps per macro-step of one subsystem) of one path from a fresh scene."""
    scene = build_scene(scenario)
    master = MASTERS["newton"](scene, dataclasses.replace(scenario.master, algorithm="newton", deadline_us=None,
                                                          fast=fast, energy_guard="off"))
    try:
        start = scene.subsystems[0].calls["doStep"]                  # the set-up's probes not counted
        return master_seconds(master, steps, scenario.dt), (scene.subsystems[0].calls["doStep"] - start) / steps
    finally:
        master.close()
        scene.close()


def newton_rows(quick=False, progress=print):
    """{scene: {"python_s", "kernel_s", "speedup", "do_steps_per_step"}}, the smallest speedup (JSON-ready)."""
    steps, repeats = (200, 2) if quick else (1000, 3)
    rows = {}
    for name, path in SCENES.items():
        progress(f"  newton, {name}: Python loop against the kernel route")
        scenario = load_scenario(path)
        best = {"false": float("inf"), "auto": float("inf")}
        for _ in range(repeats):
            for fast in best:
                seconds, do_steps = _seconds(scenario, fast, steps)
                best[fast] = min(best[fast], seconds)
        rows[name] = {"python_s": best["false"], "kernel_s": best["auto"], "speedup": best["false"] / best["auto"],
                      "do_steps_per_step": do_steps}
    speedup = min(r["speedup"] for r in rows.values())
    return {"steps": steps, "scenes": rows, "speedup_min": speedup, "target_met": speedup >= TARGET_SPEEDUP}


def add_newton_rows(result, quick, progress):
    """The bench result with the newton rows and their target added."""
    result["newton_kernel"] = newton = newton_rows(quick, progress)
    result["targets"][TARGET] = newton["target_met"]
    return result


def report_newton(n):
    """Printed lines of the newton rows."""
    lines = [f"newton, {n['steps']} steps: master s Python / kernel (speedup), doSteps per macro-step and subsystem"]
    for name, r in n["scenes"].items():
        lines.append(f"  {name:<18}{r['python_s']:.3f} / {r['kernel_s']:.4f} ({r['speedup']:.1f}x)   "
                     f"{r['do_steps_per_step']:.2f} doSteps")
    return lines
