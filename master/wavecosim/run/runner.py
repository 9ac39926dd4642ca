"""Runs one scenario with one master (`run`): the run (run/live.py, LiveRun) and, when asked, a
monolithic reference in lockstep (its own LiveRun), so errors are computed as both runs stream and
memory does not grow with the number of steps; the loop over the macro-steps, Ctrl-C and the
writer's hand-over.
"""
import signal
import time
from contextlib import contextmanager
from pathlib import Path

from ..errors import ConfigError, Interrupted, RunFailed, SimulationEnded, Terminated, WavecosimError
from ..scenario.config import SIGNALS_MASTER
from . import containment
from .bounds import named_for_cause
from .live import BLOCK_STEPS, LiveRun
from .observers.errors import error_observers, stored_reference, stored_rows
from .parts import OBSERVERS, STEP_COLUMNS, STEP_DESCRIBED, _once, _warn_stderr, open_parts
from .recorder import Interrupts, write_json
from .result import RunResult, grid_clock, grid_inverse, grid_times

__all__ = ["BLOCK_STEPS", "LiveRun", "OBSERVERS", "STEP_COLUMNS", "STEP_DESCRIBED", "open_parts", "RunResult",
           "grid_clock", "grid_inverse", "grid_times", "run", "check_steps", "reference_scenario", "MAX_STEPS"]

HAND_OVER_S = 1.0                      # rows booked are handed to the writer at least this often
MAX_STEPS = 10 ** 8                    # more macro-steps than this only when asked (--force, max_steps=None)


def run(scenario, out_dir=None, *, label=None, reference=None, certificates=True, progress=None, warn=None,
        file_suffix=True, output_interval=1, formats=("csv",), max_steps=MAX_STEPS) -> RunResult:
    """Run `scenario` with its master; stream trajectory.csv and steps.csv into out_dir when given.

    reference: None (no errors), a RunResult of the monolithic reference, or "lockstep" (run the
    monolithic reference alongside, writing its files with the label "monolithic"; only where the
    scene has power bonds: without them there is no interface to solve monolithically). Raises
    RunFailed (with .result) on a failure, Interrupted (with .result) on Ctrl-C; a run of more than
    max_steps macro-steps is refused before anything is opened or allocated."""
    check_steps(scenario, max_steps)
    warn = _once(warn or _warn_stderr)                 # the lockstep reference repeats set-up notes
    if reference == "lockstep" and (not scenario.couplings or scenario.master.tolerance is not None):
        reference = None                   # no same-grid reference for a varying step: true_error instead
    with _set_up_summary(scenario, out_dir, label, file_suffix):
        live = LiveRun(scenario, out_dir, label, certificates, warn, file_suffix, output_interval, formats)
    ref = None
    try:
        rows = None
        if not scenario.couplings:         # no power bond: no monolithic reference, no errors
            reference = None
        if reference == "lockstep":
            try:
                ref = LiveRun(reference_scenario(scenario), out_dir, "monolithic", False, warn, True,
                              output_interval, formats, share=live.scene)
            except ConfigError as exc:     # e.g. an FMU without state save that only the reference rolls back
                raise type(exc)(f"{exc} (needed by the monolithic reference; --no-reference runs without it)") from None
            reference = lambda k: ref.recent.get(k)          # noqa: E731  (ref steps first)
        elif reference is not None:
            reference, rows = stored_reference(reference), stored_rows(reference)
        if reference is not None:
            for observer in error_observers(live.columns, live.sampler.types, scenario.error, reference, rows):
                live.add_observer(observer)
    except BaseException:
        live.close()
        raise
    contain = containment.current()
    if contain is not None:
        contain.watch(live, ref)
    status, error = _loop(live, ref, progress, contain)
    with _set_up_summary(scenario, out_dir, live.label, file_suffix):
        _raise_before_first_row(status, error, live, ref)
    message = str(error) if error else ""
    if isinstance(error, Interrupted):
        message = f"{error} after {live.steps_done} steps"
    result = live.finish(status, message)
    if ref is not None:
        result.reference = ref.finish(status, message)
    if status == "interrupted":
        raise type(error)(message, result)
    failure = error if status != "finished" else None            # SimulationEnded finishes a run
    failure = failure or live.write_error or (ref.write_error if ref is not None else None)
    if failure is not None:
        raise RunFailed(failure, result) from failure
    return result


@contextmanager
def _set_up_summary(scenario, out_dir, label, file_suffix):
    """A run that fails before its first row still leaves its summary.json (0 steps, its status and the
    error's line) in out_dir, as every run that started does; the error is raised again. Bad input
    (a ConfigError: nothing ran) leaves none."""
    try:
        yield
    except WavecosimError as exc:
        if out_dir is not None and not isinstance(exc, ConfigError):
            label = label or f"{scenario.master.algorithm}_K{scenario.master.K}"
            path = Path(out_dir) / f"summary{'_' + label if file_suffix else ''}.json"
            try:
                write_json(path, {"label": label, "master": scenario.master.algorithm, "steps": 0,
                                  "status": exc.status, "message": f"{exc} (during set-up)"})
            except WavecosimError:
                pass
        raise


def _raise_before_first_row(status, error, live, ref):
    """A run that failed before one of its parts had its first row (an FMU's NaN at t = 0 in the
    reference, which starts first) has nothing to write: its FMUs are released and its error raised."""
    parts = [p for p in (ref, live) if p is not None]
    if status in ("finished", "interrupted") or all(p.calls_at_start is not None for p in parts):
        return
    for part in parts:
        part.close()
    raise error


def check_steps(scenario, max_steps=MAX_STEPS):
    """A ConfigError when the scenario has more than max_steps macro-steps (None: no limit)."""
    if max_steps is not None and scenario.n_steps > max_steps:
        raise ConfigError(f"{scenario.source}: T / dt = {scenario.n_steps:,} macro-steps, over the limit of "
                          f"{max_steps:,} (pass --force, or max_steps=None in Python, to run it anyway)")


def _progress_of(live, n):
    """Steps done as the progress shows them: n, or the share of the time made, in fixed steps (all
    of them only once the run has ended)."""
    if not live.master.variable:
        return n
    if not live.more(n):
        return live.n_steps
    return min(live.n_steps - 1, round((live.time_of(n) - live.t0) / live.dt))


def _loop(live, ref, progress, contain=None):
    """Every macro-step of the run (and of its lockstep reference); returns (status, exception).
    Rows go to the writer at least every HAND_OVER_S seconds; a supervised run (contain) is told
    which run makes the next steps, and its rows are durable as they are committed."""
    every = max(1, live.n_steps // 200)
    active = contain.active if contain is not None else (lambda part: None)
    for part in (live, ref) if contain is not None else ():
        if part is not None:
            part.make_durable(contain.channel.folder)
    with Interrupts() as stop:
        try:
            for part in (ref, live):
                if part is not None:
                    active(part)
                    part.start()
            n, handed = 0, time.perf_counter()
            while live.more(n):
                count = live.block_size(n)
                if ref is not None:
                    active(ref)
                    count = min(count, ref.lead(n, n + count) - n)
                    if count <= 0:
                        raise ref.failure
                active(live)
                done = live.advance(n, count)
                stop.check()
                if progress and ((n + done) // every > n // every or not live.more(n + done)):
                    progress(_progress_of(live, n + done), live.n_steps)
                n += done
                if time.perf_counter() - handed > HAND_OVER_S:
                    for part in (ref, live):
                        if part is not None:
                            part.hand_over()
                    handed = time.perf_counter()
        except KeyboardInterrupt:
            error = Terminated if stop.signal == signal.SIGTERM else Interrupted
            return "interrupted", error("stopped by SIGTERM" if stop.signal == signal.SIGTERM
                                        else "interrupted by the user")
        except SimulationEnded as exc:              # an FMU ended it: finished, with the steps before
            return "finished", exc
        except WavecosimError as exc:
            failed = ref if ref is not None and exc is ref.failure else live
            exc = named_for_cause(failed.scene, exc)
            return exc.status, exc
    return "finished", None


def reference_scenario(scenario):
    """The monolithic reference of a scenario: interface Newton at every macro-step; the explicit
    master where there is no power bond to solve (signals only)."""
    return scenario.with_master(algorithm="newton" if scenario.couplings else SIGNALS_MASTER)

