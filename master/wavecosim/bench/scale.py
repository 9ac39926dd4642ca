"""`wavecosim bench`, scale rows: what one inner iteration costs per subsystem as N grows.

A chain of N ChainLink FMUs (configs/chain.yaml's links, written with `repeat:`), N = 8, 64, 512.
For each N one scene is built; each timing runs a fresh master on it for K = 0, 10, 20 and takes the
fastest of its macro-steps 1 .. steps - 1 (step 0 warms up), each step one call, over a few repeats:
on a loaded machine a 2 ms step (N = 512, K = 20) is preempted far more often than a 25 µs one
(N = 8), so a whole-run or median figure measures the load, the fastest step the work. The cost
of an inner iteration is the slope of µs per macro-step against K (least squares), divided by N:
linear cost in N keeps it flat. Rows: `fast` (the C kernel, one
call per macro-step) and `python` (the readable reference DRMaster, fewer steps).
"""
import dataclasses
import time

from .common import slope
from ..scenario.config import parse_scenario
from ..masters.dr import DRMaster
from ..masters.dr_fast import FastDRMaster
from ..core.scene import build_scene

SIZES = (8, 64, 512)
KS = (0, 10, 20)
TARGET_RATIO = 1.5          # µs per subsystem per iteration at N = 512 over N = 8
LINK = {"m": 1.0, "k": 100.0, "c": 0.05}
PORT = {"wave_in": ["a_left", "a_right"], "wave_out": ["b_left", "b_right"], "effort": ["e_left", "e_right"],
        "flow": ["f_left", "f_right"], "physical_in": ["F_left", "u_right"], "input": ["effort", "flow"],
        "energy": "H"}


def chain_raw(n, T=2.0):
    """configs/chain.yaml for n links (a hammer blow on the first, the last tied to a wall), as a
    scenario mapping in the repeat form."""
    return {
        "name": f"chain_{n}", "dt": 0.01, "T": T, "gamma": 0.4,
        "subsystems": {
            "L0": {"fmu": "ChainLink", "parameters": LINK, "start": {"q": 0.0, "v": 1.0, "d": 0.0}, "gamma": 0.4,
                   "port": PORT},
            "L{i}": {"repeat": {"i": f"1..{n - 1}"}, "fmu": "ChainLink", "parameters": LINK,
                     "start": {"q": 0.0, "v": 0.0, "d": 0.0}, "gamma": 0.4, "port": PORT}},
        "couplings": [{"type": "free_end", "ports": ["L0[0]"]},
                      {"repeat": {"i": f"0..{n - 2}"}, "type": "equal_effort_opposite_flow",
                       "ports": ["L{i}[1]", "L{i+1}[0]"]},
                      {"type": "clamped_end", "ports": [f"L{n - 1}[1]"]}],
        "master": {"algorithm": "dr", "K": 50},
        "outputs": {"q{i}": {"repeat": {"i": f"0..{n - 1}"}, "value": "L{i}.q"}},
        "error": [{"repeat": {"i": f"0..{n - 1}"}, "value": "q{i}"}],
    }


def chain_scenario(n, T=2.0):
    return parse_scenario(chain_raw(n, T), f"<chain of {n} links>")


def _fastest_step_us(scene, scenario, path, K, steps):
    """µs of the fastest of macro-steps 1 .. steps - 1 of a fresh master on the scene (step 0 untimed)."""
    settings = dataclasses.replace(scenario.master, K=K, eps=None, deadline_us=None, fast="true", threads="1")
    master = DRMaster(scene, settings) if path == "python" else FastDRMaster(scene, settings)
    times = []
    try:
        master.step(0, 0.0)
        for n in range(1, steps):
            started = time.perf_counter()
            master.step(n, n * scenario.dt)
            times.append(time.perf_counter() - started)
        return 1e6 * min(times)
    finally:
        master.close()


def one_size(n, steps, repeats):
    """{path: {"us_per_step": {K: µs}, "us_per_subsystem_iter": µs}} and the scene's set-up seconds."""
    scenario = chain_scenario(n)
    started = time.perf_counter()
    scene = build_scene(scenario)
    build_s = time.perf_counter() - started
    rows = {}
    try:
        for path, path_steps in (("fast", steps), ("python", max(3, steps // 10))):
            best = {K: float("inf") for K in KS}
            for _ in range(repeats):
                for K in KS:
                    best[K] = min(best[K], _fastest_step_us(scene, scenario, path, K, path_steps))
            per_iter = slope(KS, [best[K] for K in KS])
            rows[path] = {"steps": path_steps, "us_per_step": {str(K): v for K, v in best.items()},
                          "us_per_subsystem_iter": per_iter / n}
    finally:
        scene.close()
    return rows, build_s


def scale_rows(quick=False, progress=print):
    """The scale measurement for `wavecosim bench` (JSON-ready)."""
    steps, repeats = (30, 2) if quick else (100, 3)
    sizes = {}
    for n in SIZES:
        progress(f"  chain of {n} links")
        rows, build_s = one_size(n, steps, repeats)
        sizes[str(n)] = {**rows, "set_up_s": build_s}
    fast = {key: v["fast"]["us_per_subsystem_iter"] for key, v in sizes.items()}
    ratio = fast[str(SIZES[-1])] / fast[str(SIZES[0])]
    return {"us_per_subsystem_iter": fast,
            "us_per_subsystem_iter_python": {key: v["python"]["us_per_subsystem_iter"] for key, v in sizes.items()},
            "ratio_512_over_8": ratio, "sizes": sizes, "Ks": list(KS),
            "definition": "chain of N ChainLink FMUs: slope of µs per macro-step against K (least squares over "
                          "K = 0, 10, 20; each the fastest single step over the repeats) divided by N; "
                          "fast = C kernel",
            "target_met": ratio <= TARGET_RATIO}


def report_scale(scale):
    """Printed lines of the scale rows."""
    lines = [f"{'chain of N':<12}{'µs/subsystem/iteration fast':>30}{'python':>12}{'set-up s':>10}"]
    for key, v in scale["sizes"].items():
        lines.append(f"{'N = ' + key:<12}{v['fast']['us_per_subsystem_iter']:>30.3f}"
                     f"{v['python']['us_per_subsystem_iter']:>12.2f}{v['set_up_s']:>10.2f}")
    lines.append(f"N = 512 / N = 8 per subsystem and iteration (fast): {scale['ratio_512_over_8']:.2f} "
                 f"(target <= {TARGET_RATIO})")
    return lines
