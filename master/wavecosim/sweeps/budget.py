"""Sweeps: the paper's experiment (the monolithic reference and one DR run per budget K), and
general sweeps over any scenario key (`plan`, `run_sweep`; one row per run in runs.csv/runs.json)."""
import csv
import signal
import threading
import time
from contextlib import contextmanager
from pathlib import Path

from ..scenario.config import DEFAULT_CONFIG
from ..errors import ConfigError, Interrupted
from ..examples import resolve
from ..fmi.unpack import regular_file
from .execute import Task, executor, resumed, task_scenario
from ..run.recorder import write_json
from ..scenario.overrides import expand, short_label
from ..scenario.ssp import ssp_only
from ..run.runner import reference_scenario, run

SWEEP_FIELDS = ("K", "max_error", "rms_error", "final_error", "max_passivity_pos", "max_augmented_pos",
                "min_fne_margin", "wall_time_s")


def reference_run(scenario, out_dir=None, progress=None):
    """The monolithic discrete-time trajectory: interface Newton at every macro-step."""
    return run(reference_scenario(scenario), out_dir=out_dir, label="monolithic", progress=progress,
               certificates=False)


def sweep(scenario, Ks, out_dir, progress=None, certificates=True, reference=None, on_run=None):
    """Run DR for every K in Ks against the monolithic reference; writes DIR/summary.json."""
    out_dir = Path(out_dir) if out_dir is not None else None
    reference = reference or reference_run(scenario, out_dir, progress and progress("monolithic"))
    runs, results = [], []
    for K in Ks:
        sc = scenario.with_master(algorithm="dr", K=K)
        result = run(sc, out_dir=out_dir, label=f"K{K}", progress=progress and progress(f"K = {K}"),
                     certificates=certificates, reference=reference)
        entry = {k: result.summary.get(k) for k in SWEEP_FIELDS}
        entry.update({k: v for k, v in result.summary.items() if k not in entry})
        runs.append(entry)
        results.append(result)
        if out_dir is not None:
            write_json(out_dir / "summary.json", {"scenario": scenario.name, "source": scenario.source,
                                                  "reference": reference.summary, "runs": runs})
        if on_run:
            on_run(entry)
    return reference, results, runs


def plan(config, axes, out_dir, fixed=(), sample=None, seed=0, reference=True, certificates=True,
         output_interval=1, step_timeout=None, ports=None, parameter_set=None):
    """The tasks of a general sweep, every one validated (a bad key or value is a one-line
    ConfigError before anything runs). axes: [(key, values or distribution)] from --set;
    fixed: (key, value) applied to every run (e.g. T from --T); ports, parameter_set: an SSP system's."""
    ssp_only(config, ports, parameter_set)
    config = resolve(config)
    found = regular_file(config, ConfigError) if config and not Path(config).is_dir() else config or DEFAULT_CONFIG
    if found is None:
        raise ConfigError(f"{config}: scenario file not found")
    config = str(Path(found).resolve())
    ssp = {"ports": str(Path(ports).resolve()) if ports else None, "parameter_set": parameter_set}
    points = expand(axes, sample, seed)
    keys = tuple(k for k, _ in axes)
    threads = () if any(k == "master.threads" for k, _ in [*fixed, *axes]) else (("master.threads", "1"),)
    width = len(str(len(points) - 1))
    tasks = []
    for i, point in enumerate(points):
        label = f"{i:0{width}d}_{short_label(point)}"
        tasks.append(Task(i, config, (*threads, *fixed, *point), str(Path(out_dir) / "runs" / label), label,
                          keys, reference, certificates, output_interval, step_timeout, **ssp))
    scenarios = [task_scenario(t) for t in tasks]
    if scenarios:
        preflight(scenarios[0])
    return tasks


def preflight(scenario):
    """Open (and close) the FMUs of one run, so names the FMUs lack stop the sweep before it starts."""
    from ..run.runner import open_parts
    scene, master, _ = open_parts(scenario, lambda message: None)
    master.close()
    scene.close()


def write_rows(out_dir, rows, meta):
    """OUT/runs.json (meta + rows) and OUT/runs.csv (one column per figure seen in any row)."""
    out_dir = Path(out_dir)
    write_json(out_dir / "runs.json", {**meta, "runs": rows})
    columns = list(dict.fromkeys(k for row in rows for k in row))
    tmp = out_dir / "runs.csv.part"
    with open(tmp, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, columns)
        writer.writeheader()
        writer.writerows([{k: repr(v) if isinstance(v, float) else v for k, v in row.items()} for row in rows])
    tmp.replace(out_dir / "runs.csv")


def run_sweep(tasks, out_dir, meta, workers=1, scheduler=None, resume=False, progress=None):
    """Run the tasks on the chosen executor; rows ordered by task, written as they come in.
    With resume, a task whose folder holds a finished run is not run again, and one that did not
    finish is tried once more (execute.resumed). Ctrl-C or SIGTERM keeps the rows done and raises
    Interrupted (Terminated)."""
    rows, todo = {}, list(tasks)
    if resume:
        todo = []
        for task in tasks:
            row, again = resumed(task)
            if row is not None:
                rows[task.index] = row
            else:
                todo.append(again)
    report = progress(len(tasks), len(rows)) if progress else (lambda row: None)
    ordered = lambda: [rows[i] for i in sorted(rows)]        # noqa: E731
    last_write = 0.0
    try:
        with _ctrl_c():
            for row in executor(todo, workers, scheduler):
                rows[row["index"]] = row
                report(row)
                if time.monotonic() - last_write > 1.0:
                    write_rows(out_dir, ordered(), meta)
                    last_write = time.monotonic()
    except (KeyboardInterrupt, Interrupted) as exc:
        write_rows(out_dir, ordered(), meta)
        stop = type(exc) if isinstance(exc, Interrupted) else Interrupted
        raise stop(f"sweep stopped after {len(rows)} of {len(tasks)} runs") from None
    write_rows(out_dir, ordered(), meta)
    return ordered()


@contextmanager
def _ctrl_c():
    """Ctrl-C raises KeyboardInterrupt in this process while the executor waits, even where the
    shell started it with SIGINT ignored (as for background jobs)."""
    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, signal.default_int_handler) if main else None
    try:
        yield
    finally:
        if main:
            signal.signal(signal.SIGINT, old)
