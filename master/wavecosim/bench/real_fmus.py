"""`wavecosim bench`, real_fmus rows: systems of FMUs in the style users bring, the whole run against
the floor of its FMU calls, and libcosim on the same SSD where libcosimpy is installed.

Systems: the in-repo foreign pair (configs/foreign_pair.yaml: physical ports, the wave adapter for
DR), a signal-only system (../shared/third_party/omsimulator/LinearTransformation, else SIGNAL_PAIR
built here) and the dcmotor SSD with its ports (../shared/third_party/dcmotor), each
with the masters of MASTERS it can run. Per row, side by side in one process:
  run_us_per_step    the whole run per macro-step (`run()` as `wavecosim run --no-certificates
                     --no-reference` makes it, rows kept in memory: loop_time_s / steps), best of
                     the repeats;
  floor_us_per_step  the same FMU calls in the same order, with the same arguments, made from C
                     alone on fresh instances (kernel/floor.py: recorded from one run, replayed),
                     best of the repeats;
  added_us_per_step  run minus floor: what the master adds to each macro-step (stepping logic, the
                     readings, the observers' columns, the rows), whatever the FMUs cost;
  libcosim_us_per_step  libcosim's fixed-step master on the same SSD (explicit rows; None where
                     libcosimpy is missing or refuses the file, with the reason).
  calls_per_step     the run's FMU calls per macro-step by kind (summary.json's fmu_calls: doStep,
                     save, restore, get, set), what the floor makes again.
The repeats go in rounds over every row, so a slow spell of the machine hits them alike; in each
round a row whose run is shorter than SHORT_RUN_S is timed SHORT_TRIES times.
"""
import os
import time
from pathlib import Path

from ..examples import path as example, third_party
from ..errors import ConfigError, WavecosimError
from ..fmi.fmu import interposed
from ..kernel.floor import FloorRecorder
from ..run.runner import open_parts, run
from ..scenario.config import load_scenario, parse_scenario
from ..scenario.ssp import load_ssp
from .peers import Refused, libcosim_execution

MASTERS = (("explicit", {}), ("gauss-seidel", {}), ("dr", {"K": 5, "threads": "1"}))
TARGET_FLOOR = 1.3        # whole run <= this times the floor on every row
REPEATS = 5               # rounds of the full bench (best of them: a shared machine's slow spells hit single rounds)
SHORT_RUN_S, SHORT_TRIES = 0.05, 3      # a row whose run is shorter is timed this many times per round
SIGNAL_PAIR = {           # two of our LinearSides joined by signal connections alone (no power bond)
    "name": "signal_pair", "dt": 0.001, "T": 1.0,
    "subsystems": {"A": {"fmu": "LinearSide", "parameters": {"m2": 1.0, "k2": 10.0}, "start": {"q2": 0.1}},
                   "B": {"fmu": "LinearSide", "parameters": {"m2": 2.0, "k2": 5.0}}},
    "signals": [{"from": "A.q2", "to": "B.F", "factor": 3.0}, {"from": "B.q2", "to": "A.F", "factor": -1.0,
                                                                "offset": 0.5}],
    "outputs": {"qA": "A.q2", "qB": "B.q2"},
}


def signal_pair():
    """The signal-only system built from our own FMUs (SIGNAL_PAIR)."""
    return parse_scenario(SIGNAL_PAIR, "signal_pair")


def quiet(message):
    """Set-up notes are not what the bench reports."""


def _systems():
    """[(name, scenario or None, SSD path or None, why it is missing)] of the systems here."""
    out = [("foreign_pair", load_scenario(example("foreign_pair")), None, None)]
    shared = third_party() or Path("/nonexistent")
    lt = shared / "omsimulator" / "LinearTransformation"
    try:
        out.append(("LinearTransformation", load_ssp(lt)[0], lt / "SystemStructure.ssd", None))
    except WavecosimError:                      # absent, or not readable here: our own signal pair
        out.append(("signal_pair", signal_pair(), None, None))
    dc = shared / "dcmotor" / "SystemStructure.ssd"
    if dc.exists():
        out.append(("dcmotor", load_ssp(dc, example("dcmotor_ports"))[0], dc, None))
    return out


def _whole_run(scenario):
    """µs per macro-step of the whole run (loop_time_s / steps), the master's share, and the steps."""
    s = run(scenario, certificates=False, warn=quiet).summary
    return 1e6 * s["loop_time_s"] / s["steps"], s


def _recorded(scenario):
    """A FloorRecorder holding the FMU calls of one run of the scenario."""
    recorder = FloorRecorder()
    try:
        with interposed(recorder.hook):
            recorder.start()
            run(scenario, certificates=False, warn=quiet)
    finally:
        recorder.stop()
    return recorder


def _floor(scenario, recorder):
    """µs per macro-step of the recorded FMU calls made again on freshly set-up instances."""
    scene, master, _ = open_parts(scenario, quiet)
    try:
        master.close()
        fmus = {s.name: (s.fmu.component, s.fmu.function_pointer) for s in scene.subsystems + scene.signal_only}
        return 1e6 * recorder.replay(fmus) / scenario.n_steps
    finally:
        scene.close()


def libcosim_us_per_step(ssd, dt, steps):
    """µs per macro-step of libcosim's fixed-step master on the SSD (steps of dt), or (None, why)."""
    try:
        execution = libcosim_execution(ssd, dt)
    except (ConfigError, Refused) as exc:         # not installed (the line names the extra), or refused
        return None, str(exc)
    started = time.perf_counter()
    if not execution.step(steps):
        return None, "libcosim's step failed"
    return 1e6 * (time.perf_counter() - started) / steps, None


def _rows(systems, steps=None):
    """The rows to time: one per system and master (the masters a system's scene can run), each run
    `steps` macro-steps when given (else the scenario's)."""
    rows = []
    for name, scenario, ssd, why in systems:
        if scenario is None:
            rows.append({"name": name, "master": None, "skipped": why})
            continue
        for master, changes in MASTERS:
            if master != "explicit" and not scenario.couplings:     # without power bonds: explicit only
                continue
            sc = scenario.with_master(algorithm=master, **changes)
            if steps is not None:
                sc = sc.with_changes(T=sc.start_time + steps * sc.dt)
            rows.append({"name": name, "master": master, "K": sc.master.K if master == "dr" else None,
                         "steps": sc.n_steps, "scenario": sc, "ssd": ssd})
    return rows


def _tries(r):
    """Whole runs (each with its floor) of a row per round: a run of a few milliseconds is at the
    mercy of a single slow spell of a shared machine, so it is timed SHORT_TRIES times."""
    return SHORT_TRIES if r["run_us_per_step"] * r["steps"] < 1e6 * SHORT_RUN_S else 1


def _time_row(r):
    """One whole run and one floor of a row, each kept when it is the best so far."""
    us, summary = _whole_run(r["scenario"])
    r["run_us_per_step"] = min(r["run_us_per_step"], us)
    r["fast_path"], r["block_steps"] = summary["fast_path"], summary["block_steps"]
    r["calls_per_step"] = {k: n / summary["steps"] for k, n in summary["fmu_calls"].items()}     # the run's own
    r["floor_us_per_step"] = min(r["floor_us_per_step"], _floor(r["scenario"], r["recorder"]))


def real_fmus_rows(quick=False, progress=print):
    """The rows (JSON-ready) and whether every one meets the targets."""
    repeats = 1 if quick else REPEATS
    rows = _rows(_systems(), 100 if quick else None)
    timed = [r for r in rows if "scenario" in r]
    for r in timed:
        progress(f"  real FMUs: recording the FMU calls of {r['name']}, {r['master']}")
        r["recorder"] = _recorded(r["scenario"])
        r["run_us_per_step"] = r["floor_us_per_step"] = float("inf")
    for k in range(repeats):
        progress(f"  real FMUs: round {k + 1}/{repeats}")
        for r in timed:
            for _ in range(1 if quick else _tries(r)):
                _time_row(r)
            if r["ssd"] is not None and r["master"] == "explicit":
                us, why = libcosim_us_per_step(r["ssd"], r["scenario"].dt, r["steps"])
                r["libcosim_us_per_step"] = us if us is None or r.get("libcosim_us_per_step") is None \
                    else min(us, r["libcosim_us_per_step"])
                r["libcosim_note"] = why
    for r in timed:
        r["fmu_calls"] = r.pop("recorder").calls
        r["run_over_floor"] = r["run_us_per_step"] / r["floor_us_per_step"]
        r["added_us_per_step"] = r["run_us_per_step"] - r["floor_us_per_step"]
        sc, ssd = r.pop("scenario"), r.pop("ssd")
        r["dt"], r["ssd"] = sc.dt, str(ssd) if ssd else None
        if r.get("libcosim_us_per_step"):
            r["run_over_libcosim"] = r["run_us_per_step"] / r["libcosim_us_per_step"]
    within = all(r["run_over_floor"] <= TARGET_FLOOR for r in timed)
    versus = [r["run_over_libcosim"] for r in timed if "run_over_libcosim" in r]
    return {"rows": rows, "repeats": repeats, "short_tries": 1 if quick else SHORT_TRIES,
            "short_run_s": SHORT_RUN_S, "load_average_1min": os.getloadavg()[0],
            "target_floor": TARGET_FLOOR, "within_floor": within,
            "explicit_not_slower_than_libcosim": all(v <= 1.0 for v in versus) if versus else None}


def report_real_fmus(result):
    """Printed lines of the real_fmus rows."""
    lines = [f"real FMUs (whole run, µs per macro-step, best of {result['repeats']}; load average "
             f"{result['load_average_1min']:.2f}):",
             f"  {'system':<22}{'master':<14}{'run':>9}{'floor':>9}{'run/floor':>11}{'added':>8}{'libcosim':>10}"
             f"{'calls':>7}  (FMU calls per macro-step: doStep save restore get set)"]
    for r in result["rows"]:
        if r.get("skipped"):
            lines.append(f"  {r['name']:<22}skipped: {r['skipped']}")
            continue
        master = r["master"] + (f" K={r['K']}" if r["K"] is not None else "")
        lc = r.get("libcosim_us_per_step")
        lines.append(f"  {r['name']:<22}{master:<14}{r['run_us_per_step']:>9.1f}{r['floor_us_per_step']:>9.1f}"
                     f"{r['run_over_floor']:>11.2f}{r['added_us_per_step']:>8.2f}{(f'{lc:.1f}' if lc else '-'):>10}"
                     f"{sum(r['calls_per_step'].values()):>7.1f}  ({' '.join(f'{n:g}' for n in r['calls_per_step'].values())})")
        if r.get("libcosim_note"):
            lines.append(f"    libcosim: {r['libcosim_note']}")
    return lines
