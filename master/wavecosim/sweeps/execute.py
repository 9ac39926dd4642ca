"""Sweep tasks as plain data, and three ways to run them: serial, a local process pool, Dask.

A Task names a scenario file, the (key, value) overrides and the run options; the process that
runs it reads the file, applies the overrides and opens its own FMUs (FMU handles cannot be
pickled). Every executor yields one row per task as tasks complete; callers order rows by index.
"""
import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..scenario.config import load_raw, parse_scenario
from ..errors import ConfigError, Interrupted, RunFailed, WavecosimError
from ..run.recorder import clean_json, write_json
from ..scenario.overrides import apply_overrides

ROW_FILE = "row.json"


@dataclass(frozen=True)
class Task:
    """One run of a sweep: scenario file, overrides ((key, value), ...), its own folder, options."""
    index: int
    config: str
    overrides: tuple
    out_dir: str
    label: str
    columns: tuple = field(default=())         # the swept keys among the overrides (row columns)
    reference: bool = True
    certificates: bool = True
    output_interval: int = 1


@lru_cache(maxsize=8)
def _raw(config, mtime):
    return load_raw(config)


def task_scenario(task):
    """The validated Scenario of a task: the file's mapping with the overrides applied."""
    path = Path(task.config)
    raw = apply_overrides(_raw(str(path), path.stat().st_mtime_ns), task.overrides)
    return parse_scenario(raw, str(path), path.parent)


def flatten(summary, prefix=""):
    """The scalar figures of a summary, nested mappings as dotted names; lists are left out."""
    out = {}
    for key, value in summary.items():
        if isinstance(value, dict):
            out.update(flatten(value, f"{prefix}{key}."))
        elif value is None or isinstance(value, (bool, int, float, str)):
            out[f"{prefix}{key}"] = value
    return out


def _run(task, warnings):
    """The summary of one run; a failed run gives the summary of what it computed."""
    from ..run.runner import run
    scenario = task_scenario(task)
    try:
        with np.errstate(all="ignore"):
            result = run(scenario, task.out_dir, label=task.label, certificates=task.certificates,
                         reference="lockstep" if task.reference else None, warn=warnings.append,
                         file_suffix=False, output_interval=task.output_interval)
        return result.summary
    except RunFailed as exc:
        return exc.result.summary


def run_task(task):
    """Run one task in this process; the row: index, label, swept values, status, figures, time."""
    started = time.perf_counter()
    Path(task.out_dir).mkdir(parents=True, exist_ok=True)
    warnings = []
    row = _row_head(task)
    try:
        summary = _run(task, warnings)
    except Interrupted:
        raise
    except WavecosimError as exc:
        summary = {"status": "failed", "message": str(exc)}
    except Exception as exc:                            # a bug must not lose the sweep: the row says it
        summary = {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
    row.update({k: v for k, v in flatten(summary).items() if k not in row and k != "label"})
    row["warnings"] = " | ".join(warnings)
    row["task_time_s"] = time.perf_counter() - started
    row = clean_json(row)                               # as a resumed row reads back: nan as "nan"
    write_json(Path(task.out_dir) / ROW_FILE, row)
    return row


def _row_head(task):
    row = {"index": task.index, "label": task.label}
    row.update((k, v) for k, v in task.overrides if k in task.columns)
    return row


def _outcome(future, task):
    """A finished future's row; a task whose worker died (or that failed outside its run) is a row too."""
    try:
        return future.result()
    except (Interrupted, KeyboardInterrupt):
        raise
    except Exception as exc:
        return clean_json({**_row_head(task), "status": "error", "message": f"{type(exc).__name__}: {exc}"})


def finished_row(task):
    """The stored row of a task whose folder holds a finished run with the same overrides, else None."""
    folder = Path(task.out_dir)
    try:
        summary = json.loads((folder / "summary.json").read_text())
        row = json.loads((folder / ROW_FILE).read_text())
    except (OSError, ValueError):
        return None
    same = all(row.get(k) == v for k, v in task.overrides if k in task.columns)
    return row if summary.get("status") == "finished" and same else None


def serial(tasks):
    """Each task in this process, in order."""
    for task in tasks:
        yield run_task(task)


def process_pool(tasks, workers):
    """A local pool of `workers` processes started with spawn (forking after the C kernel's threads
    started is unsafe); rows in completion order."""
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    futures = {pool.submit(run_task, t): t for t in tasks}
    try:
        for future in as_completed(futures):
            yield _outcome(future, futures[future])
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def dask_cluster(scheduler, workers):
    """(client, cluster): a Dask client of the scheduler at an address, or of an embedded
    LocalCluster of `workers` one-thread worker processes for scheduler "local"."""
    import logging
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("--executor dask needs Dask's distributed package: pip install 'wavecosim[dask]'") from None
    if scheduler != "local":
        return Client(scheduler), None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                           silence_logs=logging.ERROR)
    return Client(cluster), cluster


def dask(tasks, scheduler, workers):
    """The tasks on a Dask distributed cluster; rows in completion order."""
    from distributed import as_completed as completed
    client, cluster = dask_cluster(scheduler, workers)
    futures = {}
    try:
        futures = dict(zip(client.map(run_task, tasks, pure=False), tasks))
        for future in completed(list(futures)):
            yield _outcome(future, futures[future])
    finally:
        client.cancel(list(futures))
        client.close()
        if cluster is not None:
            cluster.close()


def executor(tasks, workers=1, scheduler=None):
    """The rows of `tasks` from the executor the options pick: Dask when a scheduler is given,
    else a process pool for workers > 1, else serial."""
    tasks = list(tasks)
    if not tasks:
        return iter(())
    if scheduler:
        return dask(tasks, scheduler, workers)
    if workers > 1 and len(tasks) > 1:
        return process_pool(tasks, min(workers, len(tasks)))
    return serial(tasks)
