"""Sweep tasks as plain data, and three ways to run them: serial (in this process), local supervised
child processes, Dask.

A Task names a scenario file, the (key, value) overrides and the run options; the process that
runs it reads the file, applies the overrides and opens its own FMUs (FMU handles cannot be
pickled). Every executor yields one row per task as tasks complete; callers order rows by index.
A task runs in a supervised child of its own (run/supervisor.py), on the process pool and on a Dask
worker alike: one that crashes, calls exit() or times out is a row with that status and message,
the worker lives on, and the others go on.
"""
import json
import re
import selectors
import shutil
import signal
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..scenario.config import load_raw, parse_scenario
from ..errors import ConfigError, Interrupted, RunFailed, Terminated, WavecosimError, optional
from ..run.outputs import remove_run_files
from ..run.recorder import clean_json, write_json
from ..scenario.overrides import apply_overrides
from ..scenario.ssp import import_ssp, is_ssp

ROW_FILE = "row.json"
STOPS = (signal.SIGINT, signal.SIGTERM)     # what stops a sweep
STOP_POLL_S = 0.5           # a Dask task looks this often whether its sweep was stopped
STOP_WAIT_S = 60.0          # after a stop: time the Dask sweep's runs have to stop and write their rows


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
    step_timeout: float = None                 # seconds a call into an FMU may take (None: the scenario's)
    ports: str = None                          # an SSP system's overlay (--ports) and parameter sets
    parameter_set: str = None
    attempt: int = 1                           # 2 for a failed run tried again by --resume


@lru_cache(maxsize=8)
def _raw(config, mtime):
    return load_raw(config)


@lru_cache(maxsize=8)
def _imported(config, mtime, ports, parameter_set, times):
    """An SSP system as imported (its mapping is copied before a task changes it)."""
    return import_ssp(config, ports, parameter_set, dict(times))


def task_scenario(task):
    """The validated Scenario of a task: the file's mapping (an SSP system's as imported, the times
    among the overrides given to the import) with the overrides applied."""
    path = Path(task.config)
    if is_ssp(path):
        times = tuple((k, v) for k, v in task.overrides if k in ("dt", "T", "start_time"))
        imported = _imported(str(path), path.stat().st_mtime_ns, task.ports, task.parameter_set, times)
        return parse_scenario(apply_overrides(imported.raw, task.overrides), str(imported.ssd), imported.ssd.parent)
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
    return _book_row(task, row, started)


def _book_row(task, row, started):
    """The row with its attempt and time, as a resumed row reads back (nan as "nan"), in ROW_FILE."""
    row["attempts"] = task.attempt
    row["task_time_s"] = time.perf_counter() - started
    row = clean_json(row)
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


def stored_row(task):
    """The row a task's folder holds from an earlier sweep with the same overrides, else None."""
    try:
        row = json.loads((Path(task.out_dir) / ROW_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return row if all(row.get(k) == v for k, v in task.overrides if k in task.columns) else None


def finished_row(task):
    """The stored row of a task whose folder holds a finished run with the same overrides, else None."""
    try:
        summary = json.loads((Path(task.out_dir) / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    row = stored_row(task)
    return row if summary.get("status") == "finished" else None


def resumed(task):
    """For --resume: (the stored row to keep, or None and the task to run). A finished run is kept; a
    run that did not finish is tried once more (attempt 2), and kept as it is after that."""
    row = finished_row(task)
    if row is not None:
        return row, None
    row = stored_row(task)
    if row is not None and row.get("attempts", 1) >= 2:
        return row, None
    return None, replace(task, attempt=2) if row is not None else task


def serial(tasks):
    """Each task in this process, in order."""
    for task in tasks:
        yield run_task(task)


def process_pool(tasks, workers):
    """Each task in a supervised child process of its own (forked from this one, which runs no FMU
    and no kernel thread), at most `workers` at once; rows in completion order. SIGINT and SIGTERM
    reach the running children, which stop between two steps; no task starts after one."""
    from ..run.supervisor import passing_stops
    todo, running = list(tasks), {}
    with passing_stops(list(running.values())) as stops:
        try:
            while todo or running:
                while todo and len(running) < workers and stops.signal is None:
                    task = todo.pop(0)
                    running[task.index] = (task, _start_child(task), time.perf_counter())
                    stops.children[:] = [child for _, child, _ in running.values()]
                if not running:
                    break
                for index in _ended(running):
                    task, child, started = running.pop(index)
                    stops.children[:] = [c for _, c, _ in running.values()]
                    yield _child_row(task, child, started)
        finally:
            for _, child, _ in running.values():
                child.kill()
    if stops.signal is not None:
        raise (Terminated if stops.signal == signal.SIGTERM else Interrupted)("stopped")


def supervised_task(task, stop=None):
    """One task in a supervised child of this process, waited for; its row (what a Dask worker runs:
    a crash, an exit() or a hang in the run ends the child, never the worker). stop: the name of the
    sweep's Dask stop events (_stop_events): once one is set, a task not yet begun gives None, and a
    running one passes the signal on to its child, which stops as a run of a process pool does."""
    started = time.perf_counter()
    events = _stop_events(stop)
    if _stop_signal(events):
        return None
    child, asked, looked = _start_child(task), False, time.monotonic()
    try:
        while not child.poll(0.2):
            if not asked and time.monotonic() - looked > STOP_POLL_S:
                looked, signum = time.monotonic(), _stop_signal(events)
                if signum:
                    child.stop(signum)
                    asked = True
    except BaseException:
        child.kill()
        raise
    return _child_row(task, child, started)


def _stop_events(name):
    """[(signal, Dask Event)] of a sweep's stop: the one set names the signal its command got."""
    if name is None:
        return []
    from distributed import Event
    return [(signum, Event(f"{name}-{int(signum)}")) for signum in STOPS]


def _stop_signal(events):
    """The signal of the stop event that is set, else None."""
    return next((signum for signum, event in events if event.is_set()), None)


def _start_child(task):
    from ..run.supervisor import Child

    def body():
        try:
            run_task(task)
        except Interrupted as exc:                      # stopped during its steps: its summary says so
            return exc.exit_code
        except KeyboardInterrupt:                       # stopped during its set-up
            return Interrupted.exit_code
        return 0
    remove_run_files(task.out_dir)                      # an earlier attempt's must not stand for this one
    timeout = task.step_timeout or task_scenario(task).step_timeout
    return Child(body, summary=Path(task.out_dir) / "summary.json", step_timeout=timeout, relay=False,
                 announce=False)


def _ended(running):
    """Indices of the running tasks whose child has ended (after a wait of at most 0.2 s)."""
    selector = selectors.DefaultSelector()
    for index, (_, child, _) in running.items():
        child.poll(0)
        selector.register(child.fileno(), selectors.EVENT_READ, index)
    try:
        selector.select(0.2)
    finally:
        selector.close()
    return [index for index, (_, child, _) in running.items() if child.poll(0)]


def _child_row(task, child, started):
    """The row a task's child wrote, or one made from the summary its rescue (or its parent) wrote."""
    code = child.finish()
    row = stored_row(task)
    if row is not None and row.get("attempts", 1) == task.attempt:
        return row
    try:
        summary = json.loads((Path(task.out_dir) / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        stopped = code in (Interrupted.exit_code, Terminated.exit_code)
        summary = {"status": "interrupted" if stopped else "crashed",
                   "message": "stopped before its first step" if stopped
                   else child.error or "the run's process ended without a summary"}
    row = _row_head(task)
    row.update({k: v for k, v in flatten(summary).items() if k not in row and k != "label"})
    row["warnings"] = ""
    return _book_row(task, row, started)


SCHEDULER = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")
CONNECT_TIMEOUT_S = 10          # seconds to reach a Dask scheduler before the sweep is refused


def check_scheduler(scheduler):
    """--scheduler: 'local' or an address tcp://HOST:PORT (tls:// too), checked before anything is planned."""
    found = SCHEDULER.match(scheduler or "")
    if scheduler != "local" and not (found and 0 < int(found.group(3)) < 65536):
        raise ConfigError(f"--scheduler {scheduler!r}: must be 'local' or a Dask scheduler's address "
                          f"tcp://HOST:PORT (or tls://HOST:PORT)")
    return scheduler


def dask_cluster(scheduler, workers, scratch):
    """(client, cluster): a Dask client of the scheduler at an address (reached within
    CONNECT_TIMEOUT_S), or of an embedded LocalCluster of `workers` one-thread worker processes for
    scheduler "local", its scratch space and temporary files in the folder `scratch`, ignoring SIGINT
    and SIGTERM (a stop reaches its runs through the sweep's stop events)."""
    import logging
    distributed = optional("distributed", "dask", "--scheduler (a sweep on Dask)")
    Client = distributed.Client
    if check_scheduler(scheduler) != "local":
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT_S), None
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"--scheduler {scheduler}: no Dask scheduler answered within {CONNECT_TIMEOUT_S} s "
                              f"({type(exc).__name__})") from None
    import dask.config
    settings = {"distributed.scheduler.allowed-failures": 0,     # a dead worker's task is not run again
                "temporary-directory": scratch}                  # the scheduler's scratch space
    main = threading.current_thread() is threading.main_thread()
    old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in STOPS} if main else {}    # the workers inherit it
    try:
        with dask.config.set(settings):
            cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                               dashboard_address=None, silence_logs=logging.ERROR,
                                               local_directory=scratch, env={"TMPDIR": scratch})
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
    return Client(cluster), cluster


def dask(tasks, scheduler, workers):
    """The tasks on a Dask distributed cluster, each in a supervised child of its worker; rows in
    completion order. A LocalCluster's scratch space is a temporary folder removed at the end.
    SIGINT and SIGTERM reach the running runs through the sweep's stop events: each stops between two
    steps and gives its row; no task starts after one."""
    from ..run.supervisor import passing_stops
    scratch = tempfile.mkdtemp(prefix="wavecosim-dask-")
    try:
        with passing_stops([]) as stops:
            client, cluster = dask_cluster(scheduler, workers, scratch)
            try:
                yield from _dask_rows(client, tasks, stops)
            finally:
                client.close()
                if cluster is not None:
                    cluster.close()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    if stops.signal is not None:
        raise (Terminated if stops.signal == signal.SIGTERM else Interrupted)("stopped")


def _dask_rows(client, tasks, stops):
    """The rows of the tasks as their futures complete; after a stop, those of the runs it stopped
    (within STOP_WAIT_S), then the rest is cancelled."""
    from distributed import Event, wait
    name = f"wavecosim-stop-{uuid.uuid4().hex}"
    futures = dict(zip(client.map(supervised_task, tasks, stop=name, pure=False, retries=0), tasks))
    pending, deadline = set(futures), None
    try:
        while pending and (deadline is None or time.monotonic() < deadline):
            if stops.signal is not None and deadline is None:
                Event(f"{name}-{int(stops.signal)}", client=client).set()
                deadline = time.monotonic() + STOP_WAIT_S
            try:
                done, pending = wait(pending, timeout=0.2, return_when="FIRST_COMPLETED")
            except TimeoutError:
                continue
            for future in done:
                row = _outcome(future, futures[future])
                if row is not None:
                    yield row
    finally:
        client.cancel(list(pending))


def executor(tasks, workers=1, scheduler=None):
    """The rows of `tasks` from the executor the options pick: Dask when a scheduler is given, else
    supervised child processes, `workers` at a time."""
    tasks = list(tasks)
    if not tasks:
        return iter(())
    if scheduler:
        return dask(tasks, scheduler, workers)
    return process_pool(tasks, max(1, min(workers, len(tasks))))
