"""`wavecosim bench`: what an inner iteration costs, four ways side by side in one run.

On the paper's Table I scene (configs/two_oscillators.yaml), for K = 0, 8, 50, it times N
macro-steps (master time only: no recording, no certificates) of
  naive_fmpy  Algorithm 1 written as a user would, with fmpy's FMU2Slave methods
              (getFMUstate/setFMUstate/setReal/doStep/getReal) and numpy;
  python      the readable reference DRMaster (wavecosim/masters/dr.py);
  fast_step   FastDRMaster on the C kernel (wavecosim/kernel/drkernel.py, kernel/c/drkernel.c), one call
              per macro-step (step);
  fast        the same kernel making the macro-steps in blocks of BLOCK_STEPS per call (run_steps),
              as the runner drives it;
  floor       the fast_step run's FMU calls, recorded and made again from C alone on fresh
              instances (kernel/floor.py): the same FMU calls with the same numbers, and no master
              logic at all.
Every run starts from a freshly instantiated scene and times macro-steps 1 .. N-1 (step 0 warms
up: first calls, cold caches); each figure is the best of a few repeats, taken in turn so that
load on the machine hits all paths alike.

The cost of one inner iteration (both subsystems queried once, plus the DR update) is the
marginal cost: the slope of the time per macro-step against K (least squares over K = 0, 8, 50),
so the per-step freeze, commit and call overhead do not dilute it. Also measured: the master time of the full Table I sweep (K = 0..50, 1000 steps each,
through the runner, certificates and FNE watch off), and the parallel speedup of the fast path on
the heavy scene (configs/heavy_chain.yaml): master time with threads = 1 over threads = 2,
the wave adapter's cost per query on its Python and C routes (wavecosim/bench/adapter.py), and
the deadline bound: DR with the energy ledger under master.deadline_us (light FMUs: the star at
30 µs; heavy: heavy_chain at γ = 600, 1500 µs), realised step times against deadline + one
evaluation round; and real FMUs (wavecosim/bench/real_fmus.py: the foreign pair, a signal-only
system, the dcmotor) whole runs against the floor of their own FMU calls and libcosim
(`--only real_fmus` times that part alone).
"""
import dataclasses
import os
import tempfile
import time

import numpy as np

from .adapter import adapter_bench, report_lines
from .threads import parallel_threads, report_threads
from .common import TABLE_I, make_steps, master_seconds, slope
from ..examples import path as example
from ..scenario.config import load_scenario
from ..fmi.fmu import interposed
from ..kernel.drkernel import available_cpus
from ..kernel.floor import FloorRecorder
from ..masters.dr import DRMaster
from ..masters.dr_fast import FastDRMaster
from ..run.runner import run
from ..core.scene import build_scene

HEAVY = example("heavy_chain")
KS = (0, 8, 50)
PATHS = ("naive_fmpy", "python", "fast_step", "fast", "floor")
DEADLINE_RUNS = (("star", example("star"), 30.0, 20.0, {}),
                 ("heavy_chain", HEAVY, 1500.0, 4.0, {"gamma": 600.0}))   # name, file, deadline (µs), T (s), changes
KINDS = (("plain", False, True), ("memory", False, False), ("certificates", True, True),
         ("certificates_memory", True, False))        # whole-run rows: name, certificates, CSV files
TARGETS = {"fast_over_floor_max": 1.5, "fast_over_floor_K0_max": 3.0, "naive_over_fast_min": 10.0, "sweep_master_s_max": 1.0,
           "parallel_speedup_min": 1.6, "run_over_master_max": 1.5, "run_over_master_certificates_max": 3.0}


def naive_fmpy(scene, K, n_steps):
    """Algorithm 1 the way a user writes it with fmpy and numpy; returns seconds for steps 1 ..
    n_steps - 1."""
    fmus = [s.fmu.slave for s in scene.subsystems]             # fmpy FMU2Slave objects
    a_vrs = [[s.fmu.vr(v) for v in s.port.wave_in] for s in scene.subsystems]
    b_vrs = [[s.fmu.vr(v) for v in s.port.wave_out] for s in scene.subsystems]
    parts = [slice(off, off + s.m) for s, off in zip(scene.subsystems, scene.offsets)]
    coupling = scene.wave_map()
    P, J_L = coupling.P, coupling.J_L
    dt = scene.scenario.dt
    b = np.zeros(scene.n_channels)
    started = time.perf_counter()
    for step in range(n_steps):
        if step == 1:
            started = time.perf_counter()      # step 0 warms up, as for every path
        t = step * dt
        states = [fmu.getFMUstate() for fmu in fmus]
        u = P @ b
        b_star = b
        for k in range(K):
            b_hat = np.zeros_like(u)
            for fmu, state, a_vr, b_vr, part in zip(fmus, states, a_vrs, b_vrs, parts):
                fmu.setFMUstate(state)
                fmu.setReal(a_vr, u[part])
                fmu.doStep(t, dt, noSetFMUStatePriorToCurrentPoint=False)      # the state is restored after
                b_hat[part] = fmu.getReal(b_vr)
            w = J_L @ (2 * b_hat - u)
            u_next = u + w - b_hat
            residual = np.linalg.norm(u_next - u)  # noqa: F841  (a user would look at it)
            u, b_star = u_next, b_hat
        a = P @ b_star
        b = np.zeros_like(u)
        for fmu, state, a_vr, b_vr, part in zip(fmus, states, a_vrs, b_vrs, parts):
            fmu.setFMUstate(state)
            fmu.setReal(a_vr, a[part])
            fmu.doStep(t, dt)
            b[part] = fmu.getReal(b_vr)
        for fmu, state in zip(fmus, states):
            fmu.freeFMUstate(state)
    return time.perf_counter() - started


def _settings(scenario, K, **changes):
    return dataclasses.replace(scenario.master, K=K, eps=None, deadline_us=None, **changes)


def timed(scenario, path, K, n_steps):
    """Seconds for macro-steps 1 .. n_steps - 1 of one path from a fresh scene (FMUs instantiated
    anew); step 0 runs untimed."""
    scene = build_scene(scenario)
    master = None
    try:
        if path == "naive_fmpy":
            return naive_fmpy(scene, K, n_steps)
        if path == "python":
            master = DRMaster(scene, _settings(scenario, K))
            return master_seconds(master, n_steps, scenario.dt)
        if path in ("fast", "fast_step"):
            master = FastDRMaster(scene, _settings(scenario, K, fast="true", threads="1"))
            return master_seconds(master, n_steps, scenario.dt, blocks=path == "fast")
        return floor_seconds(scenario, K, n_steps, scene)
    finally:
        if master is not None:
            master.close()
        scene.close()


def floor_seconds(scenario, K, n_steps, fresh):
    """Seconds of the FMU calls of a fast_step run of n_steps macro-steps, made again on the scene
    `fresh` (kernel/floor.py), in proportion to macro-steps 1 .. n_steps - 1 (the replay makes them all)."""
    recorder = FloorRecorder()
    try:
        with interposed(recorder.hook):
            scene = build_scene(scenario)
            master = FastDRMaster(scene, _settings(scenario, K, fast="true", threads="1"))
        try:
            recorder.start()
            make_steps(master, 0, n_steps, scenario.dt, blocks=False)
        finally:
            recorder.stop()
            master.close()
            scene.close()
        return recorder.replay({s.name: (s.fmu.component, s.fmu.function_pointer) for s in fresh.subsystems}) * (n_steps - 1) / n_steps
    finally:
        recorder.close()


def final_b(scenario, K, n_steps, path):
    """b^N of the Python reference (path "python") or of the kernel, step by step ("fast_step") or in
    blocks ("fast")."""
    scene = build_scene(scenario)
    master = (DRMaster(scene, _settings(scenario, K)) if path == "python" else
              FastDRMaster(scene, _settings(scenario, K, fast="true", threads="1")))
    try:
        make_steps(master, 0, n_steps, scenario.dt, blocks=path == "fast")
        return list(master.b)
    finally:
        master.close()
        scene.close()


def table_i(scenario, n_steps, repeats, progress=print):
    """µs per macro-step of every path at every K (best of `repeats`), and a bit-identity check."""
    best = {p: {K: float("inf") for K in KS} for p in PATHS}
    identical = True
    for K in KS:
        identical &= (final_b(scenario, K, n_steps, "fast_step") == final_b(scenario, K, n_steps, "python")
                      == final_b(scenario, K, n_steps, "fast"))
    for r in range(repeats):
        progress(f"  Table I scene: repeat {r + 1}/{repeats}")
        for K in KS:
            for path in PATHS:
                seconds = timed(scenario, path, K, n_steps)
                best[path][K] = min(best[path][K], 1e6 * seconds / (n_steps - 1))
    return best, identical


def sweep_master_time(scenario, Ks=range(51)):
    """Master seconds of the Table I sweep (K = 0..50, fast path): through the runner as
    `wavecosim sweep --no-certificates` runs it (FNE watch off too; the runner's own work between
    macro-steps leaves the caches cold for the next one), and with the master stepping alone."""
    scenario = dataclasses.replace(scenario, fne_watch=False) if hasattr(scenario, "fne_watch") else scenario
    runner_s = alone_s = 0.0
    for K in Ks:
        sc = scenario.with_master(algorithm="dr", K=K, fast="auto")
        runner_s += run(sc, certificates=False).summary["wall_time_s"]
        scene = build_scene(sc)
        master = FastDRMaster(scene, _settings(sc, K, fast="true", threads="1"))
        try:
            started = time.perf_counter()
            make_steps(master, 0, sc.n_steps, sc.dt, blocks=True)
            alone_s += time.perf_counter() - started
        finally:
            master.close()
            scene.close()
    return runner_s, alone_s


def parallel(scenario, n_steps, repeats, progress=print):
    """Fast-path master seconds with threads = 1 and 2 on the heavy scene, and what auto picks."""
    best = {"1": float("inf"), "2": float("inf")}
    for r in range(repeats):
        progress(f"  heavy scene: repeat {r + 1}/{repeats}")
        for threads in best:
            scene = build_scene(scenario)
            master = FastDRMaster(scene, _settings(scenario, scenario.master.K, fast="true", threads=threads))
            try:
                best[threads] = min(best[threads], master_seconds(master, n_steps, scenario.dt))
            finally:
                master.close()
                scene.close()
    scene = build_scene(scenario)
    master = FastDRMaster(scene, _settings(scenario, scenario.master.K, fast="true", threads="auto"))
    try:
        for n in range(3):                   # step 0 times the subsystems, step 1 tries two threads
            master.step(n, n * scenario.dt)
        auto = master.thread_note
        costs = master.costs_us
    finally:
        master.close()
        scene.close()
    return {"scene": scenario.name, "K": scenario.master.K, "steps": n_steps, "serial_s": best["1"],
            "parallel_s": best["2"], "speedup": best["1"] / best["2"], "auto": auto, "us_per_eval": costs,
            "cpus": available_cpus(), "load_average_1min": os.getloadavg()[0]}


def whole_run(scenario, K, certificates, out_dir):
    """µs per macro-step of the whole run (reading, observers, every row written) and of its master
    alone, as `wavecosim run --no-reference` does it (CSV files written; out_dir None: rows kept in
    memory only, as `wavecosim.simulate` does without out_dir)."""
    result = run(scenario.with_master(K=K), out_dir, certificates=certificates, file_suffix=False)
    s, n = result.summary, result.summary["steps"]
    return {"run_us_per_step": 1e6 * s["loop_time_s"] / n, "master_us_per_step": 1e6 * s["wall_time_s"] / n,
            "set_up_s": s["total_time_s"] - s["loop_time_s"], "steps": n}


def run_overhead(scenario, repeats, long_steps, progress=print):
    """Whole run against the master's own time at K = 0 and 50: CSV files, rows in memory only (as
    `run()` and `simulate()` keep them by default), and each with certificates on (best of `repeats`);
    and at K = 0 the same scene over `long_steps` steps (CSV and in memory, best of 3), where the
    writer threads format while the master runs. The master's own time (`master_alone_us_per_step`)
    is the fastest master time of the runs without certificates at that K and length: a run with
    certificates is divided by the master as it runs without them. The repeats go in rounds over
    every case."""
    long = scenario.with_changes(T=long_steps * scenario.dt)
    cases = [(f"{kind}_K{K}", scenario, K, cert, files, repeats) for kind, cert, files in KINDS for K in (0, 50)]
    cases += [(f"{kind}_K0_long", long, 0, False, files, 3) for kind, cert, files in KINDS[:2]]
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):                 # rounds over the cases, so a slow spell of the machine hits all
            progress(f"  whole run: round {r + 1}/{repeats}")
            for key, sc, K, cert, files, times in (c for c in cases if r < c[5]):
                measured = whole_run(sc, K, cert, tmp if files else None)
                if key not in out or measured["run_us_per_step"] < out[key]["run_us_per_step"]:
                    out[key] = measured
    for group in ("K0", "K50", "K0_long"):
        keys = [k for k in out if k.endswith(f"_{group}") and not k.endswith(f"_{group}_long")]
        alone = min(out[k]["master_us_per_step"] for k in keys if not k.startswith("certificates"))
        for k in keys:
            out[k].update(master_alone_us_per_step=alone, run_over_master=out[k]["run_us_per_step"] / alone)
    return out


def deadline_bound(quick=False, progress=print):
    """Realised step times of DR with the ledger under master.deadline_us (K = 100000, so the deadline
    ends every inner loop; serial) against the bound deadline + one evaluation round (every subsystem's
    doStep once, as measured): in kernel blocks, as `wavecosim run --no-certificates` makes them, and
    with the certificates on (the CLI default; sampled inside the same blocks, outside the step time)."""
    out = {}
    for name, path, deadline_us, T, changes in DEADLINE_RUNS:
        scenario = load_scenario(path).with_changes(T=T / 4 if quick else T, **changes)
        scenario = scenario.with_master(K=100000, eps=None, deadline_us=deadline_us, energy_guard="ledger",
                                        threads="1")
        for certificates, key in ((False, name), (True, f"{name}, certificates")):
            progress(f"  deadline bound: {key} at {deadline_us:g} µs")
            s = run(scenario, certificates=certificates).summary
            out[key] = {**s["deadline_bound"], "steps": s["steps"], "iterations_mean": s["iterations_mean"],
                        "steps_acted": s["energy_guard_steps"], "all_us": s["step_time_us"],
                        "guarded_us": s["guarded_step_time_us"], "block_steps": s["block_steps"],
                        "load_average_1min": os.getloadavg()[0]}
    return out


def with_real_fmus(result, quick, progress):
    """The result with the real_fmus rows (bench/real_fmus.py) and their targets added."""
    from .real_fmus import TARGET_FLOOR, real_fmus_rows
    rows = real_fmus_rows(quick, progress)
    result["real_fmus"] = rows
    result["targets"][f"real FMUs: whole run <= {TARGET_FLOOR} x the floor on every row"] = rows["within_floor"]
    if rows["explicit_not_slower_than_libcosim"] is not None:
        result["targets"]["real FMUs: wavecosim explicit <= libcosim per macro-step"] = \
            rows["explicit_not_slower_than_libcosim"]
    return result


def with_scale_and_classical(result, scenario, quick, progress):
    """The result with the scale rows (bench/scale.py) and the classical masters' kernel route
    (bench/classical.py) added, and their targets."""
    from .classical import classical_rows
    from .newton import add_newton_rows
    from .scale import scale_rows
    add_newton_rows(result, quick, progress)       # the newton rows (bench/newton.py)
    scale, classical = scale_rows(quick, progress), classical_rows(scenario, quick, progress)
    result.update(us_per_subsystem_iter=scale["us_per_subsystem_iter"], scale=scale, classical_kernel=classical)
    with_real_fmus(result, quick, progress)
    result["targets"].update({"N = 512 within 1.5x of N = 8 per subsystem and iteration": scale["target_met"],
                              "classical masters on the kernel >= 10x faster than their Python loops":
                              classical["target_met"]})
    return result


def real_fmus(quick, progress):
    """The real_fmus rows alone (bench/real_fmus.py)."""
    from .real_fmus import real_fmus_rows
    return real_fmus_rows(quick, progress)


def report_real(rows):
    from .real_fmus import report_real_fmus
    return report_real_fmus(rows)


PARTS = {"parallel_threads": (parallel_threads, report_threads),      # `wavecosim bench --only NAME`
         "real_fmus": (real_fmus, report_real)}


def run_part(name, quick=False, progress=print):
    """One part of the bench alone: ({name: its figures}, its printed lines)."""
    measure, lines = PARTS[name]
    figures = measure(quick, progress)
    return {name: figures, "quick": quick}, lines(figures)


def run_bench(quick=False, progress=print):
    """All measurements; returns the JSON-ready result."""
    n_steps, repeats = (200, 3) if quick else (1000, 3)
    heavy_steps, heavy_repeats = (30, 2) if quick else (100, 3)
    scenario = load_scenario(TABLE_I)
    per_step, identical = table_i(scenario, n_steps, repeats, progress)
    per_iter = {p: slope(KS, [per_step[p][K] for K in KS]) for p in PATHS}
    progress("  Table I sweep K = 0..50 through the runner")
    sweep_s, sweep_alone_s = sweep_master_time(scenario)
    par = parallel(load_scenario(HEAVY), heavy_steps, heavy_repeats, progress)
    threads = parallel_threads(quick, progress)
    whole = run_overhead(scenario.with_changes(T=n_steps * scenario.dt), 3 * repeats,   # runs of ~1-30 ms: more repeats
                         10_000 if quick else 100_000, progress)
    over = {k: v["run_over_master"] for k, v in whole.items()}
    ratios = {"fast_over_floor": per_iter["fast"] / per_iter["floor"],
              "fast_over_floor_K0": per_step["fast"][0] / per_step["floor"][0],
              "fast_step_over_floor_K0": per_step["fast_step"][0] / per_step["floor"][0],
              "naive_over_fast": per_iter["naive_fmpy"] / per_iter["fast"],
              "python_over_fast": per_iter["python"] / per_iter["fast"]}
    return with_scale_and_classical({
        "scene": scenario.name, "steps": n_steps, "repeats": repeats, "quick": quick,
        "us_per_step": {p: {str(K): v for K, v in per_step[p].items()} for p in PATHS},
        "us_per_iter": per_iter,
        "us_per_iter_definition": "slope of µs per macro-step against K (least squares over K = 0, 8, 50; "
                                  "each point the best of the repeats): one inner iteration, both subsystems",
        "ratios": ratios,
        "fast_bit_identical_to_python": identical,
        "sweep": {"Ks": "0..50", "steps_per_run": scenario.n_steps, "master_time_s": sweep_s,
                  "master_alone_s": sweep_alone_s},
        "parallel": par,
        "parallel_speedup": par["speedup"],
        "parallel_threads": threads,
        "whole_run": whole,
        **run_ratios(whole),
        "wave_adapter": adapter_bench(quick, 1 if quick else repeats, progress),
        "deadline_bound": deadline_bound(quick, progress),
        "targets": {
            "fast_over_floor <= 1.5": ratios["fast_over_floor"] <= TARGETS["fast_over_floor_max"],
            "fast / floor at K = 0 <= 3": ratios["fast_over_floor_K0"] <= TARGETS["fast_over_floor_K0_max"],
            "naive_over_fast >= 10": ratios["naive_over_fast"] >= TARGETS["naive_over_fast_min"],
            "sweep master time < 1 s": sweep_s < TARGETS["sweep_master_s_max"],
            "parallel speedup >= 1.6": par["speedup"] >= TARGETS["parallel_speedup_min"],
            "parallel_threads speedup >= 0.8 x min(threads, CPUs)": threads["target_met"],
            **run_targets(over),
        },
    }, scenario, quick, progress)


def run_ratios(whole):
    """The whole-run rows as the JSON's ratio keys: run_over_master is the issue's, run() with its
    default outputs (the rows in memory); the CLI's CSV files beside it."""
    over = {k: v["run_over_master"] for k, v in whole.items()}
    pair = (lambda kind: {"K0": over[f"{kind}_K0"], "K50": over[f"{kind}_K50"]})
    return {"run_over_master": pair("memory"), "run_over_master_certificates": pair("certificates_memory"),
            "run_over_master_csv_files": pair("plain"),
            "run_over_master_certificates_csv_files": pair("certificates"),
            "run_over_master_long_K0": {"csv": over["plain_K0_long"], "memory": over["memory_K0_long"],
                                        "steps": whole["plain_K0_long"]["steps"]}}


def run_targets(over):
    """The whole-run targets: run() (rows in memory, its default) <= 1.5 x the master alone and <= 3 x
    with certificates; the same figures with CSV files (wavecosim run) beside them."""
    out = {}
    for where, plain, cert in (("run() default: rows in memory", "memory", "certificates_memory"),
                               ("CSV files", "plain", "certificates")):
        out[f"run / master <= 1.5, {where}"] = max(over[f"{plain}_K0"], over[f"{plain}_K50"]) \
            <= TARGETS["run_over_master_max"]
        out[f"run / master <= 3 with certificates, {where}"] = max(over[f"{cert}_K0"], over[f"{cert}_K50"]) \
            <= TARGETS["run_over_master_certificates_max"]
    return out


def report(result):
    """The printed table."""
    lines = [f"{result['scene']}: {result['steps']} macro-steps per run, best of {result['repeats']}",
             f"{'path':<12}" + "".join(f"{'µs/step K=' + str(K):>15}" for K in KS) + f"{'µs/iteration':>15}"]
    for p in PATHS:
        lines.append(f"{p:<12}" + "".join(f"{result['us_per_step'][p][str(K)]:>15.2f}" for K in KS)
                     + f"{result['us_per_iter'][p]:>15.3f}")
    r = result["ratios"]
    lines.append(f"fast / floor = {r['fast_over_floor']:.2f}   naive_fmpy / fast = {r['naive_over_fast']:.1f}   "
                 f"python / fast = {r['python_over_fast']:.1f}   (per inner iteration)")
    lines.append(f"per macro-step at K = 0: fast / floor = {r['fast_over_floor_K0']:.2f}, "
                 f"fast_step / floor = {r['fast_step_over_floor_K0']:.2f}")
    lines.append(f"fast path bit-identical to the Python reference: {result['fast_bit_identical_to_python']}")
    s = result["sweep"]
    lines.append(f"Table I sweep K = {s['Ks']} x {s['steps_per_run']} steps: master time {s['master_time_s']:.3f} s "
                 f"through the runner, {s['master_alone_s']:.3f} s stepping the master alone")
    p = result["parallel"]
    lines.append(f"{p['scene']} (K = {p['K']}, {p['steps']} steps, {p['cpus']} CPUs, load average "
                 f"{p['load_average_1min']:.2f}): threads=1 {p['serial_s']:.3f} s, threads=2 {p['parallel_s']:.3f} s, "
                 f"speedup {p['speedup']:.2f}x")
    lines.append(f"  threads: auto -> {p['auto']}")
    lines.extend(report_threads(result["parallel_threads"]))
    lines.append(f"{'whole run':<24}{'µs/step run':>13}{'its master':>12}{'master alone':>14}{'run / master alone':>20}")
    for key, w in result["whole_run"].items():
        lines.append(f"{key:<24}{w['run_us_per_step']:>13.2f}{w['master_us_per_step']:>12.2f}"
                     f"{w['master_alone_us_per_step']:>14.2f}{w['run_over_master']:>20.2f}")
    lines.extend(report_lines(result["wave_adapter"]))
    lines.append(f"{'deadline bound (µs)':<26}{'deadline':>9}{'bound':>9}{'median':>9}{'p99':>9}{'max':>10}"
                 f"{'within':>8}{'on CPU':>8}{'acted':>7}{'guarded median / max':>22}")
    for name, d in result["deadline_bound"].items():
        a, g = d["all_us"], d["guarded_us"]
        guarded = f"{g['median']:.1f} / {g['max']:.1f}" if g else "-"
        on_cpu = "-" if d["on_cpu_within"] is None else f"{100 * d['on_cpu_within']:.1f}%"
        lines.append(f"{name:<26}{d['deadline_us']:>9.1f}{d['bound_us']:>9.1f}{a['median']:>9.1f}{a['p99']:>9.1f}"
                     f"{a['max']:>10.1f}{100 * d['within']:>7.1f}%{on_cpu:>8}{d['steps_acted']:>7}{guarded:>22}")
    from .classical import report_classical
    from .scale import report_scale
    lines.extend(report_scale(result["scale"]))
    lines.extend(report_classical(result["classical_kernel"]))
    from .newton import report_newton
    lines.extend(report_newton(result["newton_kernel"]))
    lines.extend(report_real(result["real_fmus"]))
    lines.append("targets: " + ", ".join(f"{k}: {'met' if v else 'MISSED'}" for k, v in result["targets"].items()))
    return lines
