"""Runs one scenario with one master: the macro-step loop, certificates, streaming output, summary."""
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import certificates as cert
from .errors import ConfigError, Interrupted, NumericalError, WavecosimError
from .fne_watch import FneWatch, trace_impedances, trace_margins
from .gamma_tuning import GammaTuner, scene_gammas
from .masters import MASTERS
from .masters.newton import solve_interface
from .energy_guard import EnergyGuard
from .recorder import CsvStream, write_json
from .scene import build_scene


@dataclass
class RunResult:
    """Everything a run produced; arrays hold the rows computed so far even when it failed."""
    label: str
    master: str
    K: int
    columns: list
    t: np.ndarray
    outputs: np.ndarray
    steps: dict
    summary: dict = field(default_factory=dict)
    status: str = "finished"
    message: str = ""
    units: dict = field(default_factory=dict)
    error_columns: list = field(default_factory=list)

    def column(self, name):
        return self.outputs[:, self.columns.index(name)]


def _observed(scene, scenario):
    """Per subsystem: value references of H, e, f, b and the recorded outputs, read in one call."""
    plan = []
    for s in scene.subsystems:
        names = [s.port.energy, *s.port.effort, *s.port.flow, *s.port.wave_out]
        cols = [(c, ref.split(".")[1]) for c, ref in scenario.outputs.items() if ref.split(".")[0] == s.name]
        plan.append((s, s.fmu.vrs(names + [v for _, v in cols]), [c for c, _ in cols]))
    return plan


def _units(scene, scenario):
    """{column: unit} of the recorded outputs, from the FMUs' model descriptions ('' when none)."""
    subs = {s.name: s for s in scene.subsystems}
    units = {}
    for c, ref in scenario.outputs.items():
        name, var = ref.split(".")
        units[c] = subs[name].fmu.variable(var).unit or ""
    return units


def _read(plan, m_sizes):
    """One getReal per subsystem -> (H, e, f, b per subsystem, {column: value})."""
    H, E, F, B, out = [], [], [], [], {}
    for (s, vrs, cols), m in zip(plan, m_sizes):
        v = s.fmu.get_real(vrs)
        H.append(v[0])
        E.append(list(v[1:1 + m]))
        F.append(list(v[1 + m:1 + 2 * m]))
        B.append(list(v[1 + 2 * m:1 + 3 * m]))
        out.update(zip(cols, v[1 + 3 * m:]))
    return H, E, F, B, out


def error_metrics(result: RunResult, reference: RunResult, columns):
    """Max, rms (over every grid point, t = 0 included) and final of ||(dq1, dq2, ...)||_2."""
    n = min(len(result.t), len(reference.t))
    diff = np.stack([result.column(c)[:n] - reference.column(c)[:n] for c in columns], axis=1)
    err = np.sqrt(np.sum(diff * diff, axis=1))
    return err, {"max_error": float(err.max()), "rms_error": float(np.sqrt(np.mean(err * err))),
                 "final_error": float(err[-1])}


def _stderr_warning(message):
    print(f"warning: {message}", file=sys.stderr, flush=True)


class _DeferInterrupt:
    """Holds a Ctrl-C (SIGINT) back while one step is booked and written, so the CSV files and the
    summary always agree on the number of steps; the KeyboardInterrupt is raised right after."""

    def __enter__(self):
        self.hit, self.old = False, None
        if threading.current_thread() is threading.main_thread():
            self.old = signal.signal(signal.SIGINT, self._hold)
        return self

    def _hold(self, signum, frame):
        self.hit = True

    def __exit__(self, *exc):
        if self.old is not None:
            signal.signal(signal.SIGINT, self.old)
        if self.hit and exc[0] is None:
            raise KeyboardInterrupt
        return False


def _sample_certificates(scene, master, scenario, rng, n, t):
    """Before macro-step n: the sampled FNE margin of each S_i^n (Condition 1) and a DR fixed point
    u* = P b* (eq. 18) for the augmented residual; the FMUs are left at x^n."""
    certs, u_star = scenario.certificates, None
    fne = [float("nan")] * len(scene.subsystems)
    if not (certs.fne_pairs or certs.augmented):
        return fne, u_star
    sizes = [s.m for s in scene.subsystems]
    for s in scene.subsystems:
        s.freeze(n, t)
    if certs.augmented and scenario.master.algorithm == "dr":
        b_star = solve_interface(master.S, master.P, master.b, max(sizes), scene.offsets, sizes,
                                 where=f" at step {n} (t = {t:.6g})")[0]
        u_star = list(np.asarray(master.P) @ b_star)
    if certs.fne_pairs:
        centre = scene.split(list(np.asarray(master.P) @ np.asarray(master.b)))
        fne = [cert.fne_margins(s, c, certs.fne_pairs, rng, certs.fne_scale, scenario.dt)
               for s, c in zip(scene.subsystems, centre)]
    for s in scene.subsystems:
        s.thaw()
    return fne, u_star


def run(scenario, out_dir=None, label=None, progress=None, certificates=True, reference=None, gamma=None,
        file_suffix=True, warn=None) -> RunResult:
    """Run `scenario` with its master settings; stream `trajectory.csv` and `steps.csv` into out_dir.

    `gamma` overrides the scenario's; `gamma: auto | auto-retune | fast-unsafe` is resolved here
    (gamma_tuning). `warn(line)` receives warnings (Condition 1 failing, fast-unsafe); default stderr."""
    warn = warn or _stderr_warning
    settings = scenario.master
    cls = MASTERS[settings.algorithm]
    label = label or f"{settings.algorithm}_K{settings.K}"
    N, dt = scenario.n_steps, scenario.dt
    columns = list(scenario.outputs)
    scene = build_scene(scenario, wave=cls.wave, gamma=gamma, needs_rollback=cls.needs_rollback)
    tuner = master = None
    try:                                      # set-up problems are input errors: raised as they are
        if cls.wave and gamma is None and isinstance(scenario.gamma, str):
            tuner = GammaTuner(scene, scenario.gamma, warn if settings.algorithm == "dr" else None)
            tuner.initial([0.0] * scene.n_channels)                  # sets the scene's per-subsystem gammas
        master = cls(scene, settings, gamma=gamma) if cls.wave else cls(scene, settings)
        if tuner and tuner.retune and not hasattr(master, "set_gamma"):
            raise ConfigError(f"{scenario.source}: gamma: auto-retune needs a master that can change gamma between "
                              f"macro-steps (dr, newton), not {settings.algorithm}")
    except BaseException:
        if master is not None:
            master.close()
        scene.close()
        raise
    units = _units(scene, scenario)
    sizes = [s.m for s in scene.subsystems]
    names = [s.name for s in scene.subsystems]
    t_rows, out_rows = [], []
    steps = {k: [] for k in ("iterations", "residual", "passivity", "augmented", "fne", "supply", "H", "gamma",
                             "fne_watch")}
    watch = None
    traj = diag = None
    status, message = "finished", ""
    master_time = 0.0
    calls = {"doStep": 0, "save": 0, "restore": 0}
    started = time.perf_counter()
    guard = None
    try:
        if scenario.fne_watch and settings.algorithm == "dr":
            watch = FneWatch(scene, warn)
        if (watch or tuner and tuner.retune) and hasattr(master, "trace"):
            master.trace = []                                        # keep the inner loop's (u, S(u)) pairs
        plan = _observed(scene, scenario)
        if out_dir is not None:
            out_dir = Path(out_dir)
            suffix = f"_{label}" if file_suffix else ""
            traj = CsvStream(out_dir / f"trajectory{suffix}.csv", ["t", *columns])
            diag = CsvStream(out_dir / f"steps{suffix}.csv",
                             ["t", "iterations", "inner_residual", "reason", *[f"r_{n}" for n in names],
                              "augmented", "interface_supply", "H_total", "fne_min",
                              *([f"gamma_{n}" for n in names] if cls.wave else []), "fne_watch"])
        H, _, _, _, out = _read(plan, sizes)
        t_rows.append(0.0)
        out_rows.append([out[c] for c in columns])
        if traj:
            traj.write([0.0, *out_rows[-1]])
        steps["H"].append(sum(H))
        guard = EnergyGuard(scene, master, sum(H)) if settings.algorithm == "dr" and settings.energy_guard else None
        rng = np.random.default_rng(scenario.certificates.fne_seed)
        wave_certs = certificates and cls.wave
        for n in range(N):
            t = n * dt
            fne, u_star = [float("nan")] * len(names), None
            if tuner:
                tuner.between_steps(master, n, t)                    # gamma changes only between macro-steps
            probed = None
            if watch and (settings.K < 2 or getattr(master, "trace", None) is None):
                probed = watch.probe(master.b, n, t, master.P)       # no inner iterates to read margins from
            if wave_certs:
                fne, u_star = _sample_certificates(scene, master, scenario, rng, n, t)
            fne_min = min(fne) if all(v == v for v in fne) else float("nan")
            before = {k: sum(s.calls[k] for s in scene.subsystems) for k in calls}
            t0 = time.perf_counter()
            if guard:
                guard.before(n, t)
            log = master.step(n, t)
            master_time += time.perf_counter() - t0
            H_new, E, F, B, out = _read(plan, sizes)
            if guard:
                t0 = time.perf_counter()
                redo = guard.after(n, t, sum(H_new))
                master_time += time.perf_counter() - t0
                if redo is not None:
                    log = redo
                    H_new, E, F, B, out = _read(plan, sizes)
            for k in calls:
                calls[k] += sum(s.calls[k] for s in scene.subsystems) - before[k]
            if tuner and tuner.retune and getattr(master, "trace", None):
                tuner.observe(trace_impedances(scene, master.trace, scene_gammas(scene)))
            watched = float("nan")
            if watch:
                if probed is None and not master.trace and log.iterations >= 2:
                    master.trace = None                              # this master does not expose its queries
                watched = watch.record(n, t, probed if probed is not None else trace_margins(scene, master.trace or []))
            if cls.wave:
                a_parts = scene.split(log.a_hat)
                r = [cert.wave_passivity_residual(h0, h1, a, b) for h0, h1, a, b in zip(H, H_new, a_parts, B)]
                supply = 0.5 * (sum(x * x for x in log.a_hat) - sum(x * x for bi in B for x in bi))
            else:
                r = [cert.physical_passivity_residual(h0, h1, e, f, dt) for h0, h1, e, f in zip(H, H_new, E, F)]
                supply = sum(dt * sum(ei * fi for ei, fi in zip(e, f)) for e, f in zip(E, F))
            aug = float("nan")
            if u_star is not None and log.u0 is not None:
                aug = cert.augmented_residual(sum(H_new) - sum(H), log.u0, log.uK, u_star, log.a_hat,
                                              [x for bi in B for x in bi])
            row = [out[c] for c in columns]
            gammas = list(scene_gammas(scene).values()) if cls.wave else []
            with _DeferInterrupt():
                t_rows.append((n + 1) * dt)
                out_rows.append(row)
                for key, val in (("iterations", log.iterations), ("residual", log.residual), ("passivity", r),
                                 ("augmented", aug), ("fne", fne), ("supply", supply), ("H", sum(H_new)),
                                 ("gamma", gammas), ("fne_watch", watched)):
                    steps[key].append(val)
                if traj:
                    traj.write([(n + 1) * dt, *row])
                    diag.write([(n + 1) * dt, log.iterations, log.residual, log.reason, *r, aug, supply,
                                sum(H_new), fne_min, *gammas, watched])
            if not np.all(np.isfinite(row)) or not np.all(np.isfinite(H_new)):
                bad = next(s.name for s, h in zip(scene.subsystems, H_new) if not np.isfinite(h)) \
                    if not np.all(np.isfinite(H_new)) else "an output"
                raise NumericalError(f"non-finite value in {bad} at step {n} (t = {(n + 1) * dt:.6g})")
            H = H_new
            if progress:
                progress(n + 1, N)
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted by the user after {len(t_rows) - 1} steps"
    except WavecosimError as exc:
        status, message = "failed", str(exc)
    finally:
        for stream in (traj, diag):
            if stream:
                stream.close()
        if master is not None:
            master.close()
        scene.close()
    result = RunResult(label=label, master=settings.algorithm, K=settings.K, columns=columns,
                       t=np.array(t_rows), outputs=np.array(out_rows).reshape(len(t_rows), len(columns)),
                       steps=steps, status=status, message=message, units=units,
                       error_columns=list(scenario.error))
    result.summary = _summary(result, scenario, master_time, time.perf_counter() - started, calls, names)
    result.summary.update(getattr(master, "run_info", dict)())   # e.g. DR: fast path and threads used
    if cls.wave:
        result.summary.update(tuner.summary(steps["gamma"]) if tuner else
                              {"gamma_mode": "fixed", "gamma_initial": scene_gammas(scene),
                               "gamma_final": scene_gammas(scene)})
    if watch:
        result.summary.update(watch.summary())
    if guard is not None:
        result.summary["energy_guard_steps"] = guard.redone
    if reference is not None and len(reference.t) and len(result.t) and scenario.error:
        err, metrics = error_metrics(result, reference, scenario.error)
        result.summary.update(metrics)
        result.steps["error"] = err
    if out_dir is not None:
        write_json(Path(out_dir) / (f"summary_{label}.json" if file_suffix else "summary.json"), result.summary)
    if status == "interrupted":
        raise Interrupted(message)
    if status == "failed":
        raise type_of_failure(message, result)
    return result


class RunFailed(WavecosimError):
    """A run stopped early; `result` holds what was computed (also on disk)."""

    def __init__(self, message, result, exit_code):
        super().__init__(message)
        self.result, self.exit_code = result, exit_code


def type_of_failure(message, result):
    code = 4 if "non-finite" in message or "Newton" in message else 3
    return RunFailed(message, result, code)


def _pos_max(values):
    arr = np.asarray([v for v in values if v == v], float)
    return float(max(0.0, arr.max())) if arr.size else float("nan")


def _finite_min(values):
    arr = np.asarray([v for v in values if v == v], float)
    return float(arr.min()) if arr.size else float("nan")


def _summary(result, scenario, master_time, total_time, calls, names):
    s = result.steps
    passivity = np.array(s["passivity"], float).reshape(-1, len(names)) if s["passivity"] else np.zeros((0, len(names)))
    H = np.array(s["H"], float)
    supply = np.array(s["supply"], float)
    n = len(s["iterations"])
    fne = np.array(s["fne"], float).reshape(-1, len(names)) if s["fne"] else np.zeros((0, len(names)))
    return {
        "label": result.label, "scenario": scenario.name, "master": result.master, "K": result.K,
        "eps": scenario.master.eps, "dt": scenario.dt, "T": scenario.T, "steps": n, "status": result.status,
        "message": result.message,
        "max_passivity_pos": _pos_max(passivity.ravel()),
        "max_passivity_pos_by_subsystem": {nm: _pos_max(passivity[:, i]) for i, nm in enumerate(names)},
        "max_augmented_pos": _pos_max(s["augmented"]),
        "min_fne_margin": _finite_min(fne.ravel()),
        "min_fne_margin_by_subsystem": {nm: _finite_min(fne[:, i]) for i, nm in enumerate(names)},
        "iterations_mean": float(np.mean(s["iterations"])) if n else 0.0,
        "iterations_max": int(max(s["iterations"])) if n else 0,
        "wall_time_s": master_time, "total_time_s": total_time,
        "real_time_factor": (n * scenario.dt) / master_time if master_time > 0 else float("nan"),
        "fmu_calls": calls,
        "H_initial": float(H[0]) if H.size else float("nan"),
        "H_final": float(H[-1]) if H.size else float("nan"),
        "max_interface_injection": _pos_max(supply),
        "energy_drift": float(supply.sum()) if supply.size else 0.0,
    }
