"""The child's side of a supervised run (run/supervisor.py starts it): a fault of an FMU (a crash, an
exit() call, a call that does not return) must not lose what was computed.

    Containment(channel, step_timeout, setup_timeout)
                                           arms kernel/c/guard.c, starts the rescue thread and the
                                           watchdog (its heartbeat tells the parent the child is alive)
    containment.watch(live, ref)           the runner's runs, finished by the rescue
    containment.active(part) / .leave()    which run is stepping now (the one an FMU fault is in)

A fault parks the faulting thread (an FMU call runs without the GIL); a call that outlives its timeout
is asked to park by the freeze signal, and when the FMU blocks, ignores or handles that signal itself
the watchdog records the freeze in its place. The rescue thread then books
the steps of a kernel block in progress, writes every run's rows, summary.json and metadata.json
with status `crashed`, `timed out` or `interrupted`, prints one line and ends the process with the
error class's exit code. The shared status page tells the parent what happened when even that
cannot run (a fault holding the GIL, a process killed outright): it then writes the summary itself.
"""
import os
import sys
import threading
import time
from pathlib import Path

from ..errors import Interrupted, StepTimeout
from ..kernel import fmicall, guard
from ..kernel.fmicall import FMI_ENTRIES
from .channel import Channel, DONE, RESCUING, RUNNING, SETUP, STOP, STOP_GRACE_S, TERM, TIMEOUT, describe, in_progress, locate

_current = None
POLLS_PER_TIMEOUT = 20            # the watchdog looks this often per timeout (at most 4 times a second)
DECLINED_TRIES = 5                # freeze requests the main thread declines (running Python) before it is interrupted
UNANSWERED_TRIES = 3              # freeze requests nobody takes (the FMU holds the signal) before the watchdog takes it


def current():
    """The Containment of this process, or None (an unsupervised run: the API)."""
    return _current


class Containment:
    """Fault handling of the one supervised run in this process."""

    def __init__(self, channel: Channel, step_timeout=None, announce=True, setup_timeout=None):
        """announce: the rescue prints the error line (a sweep's runs leave that to the sweep);
        setup_timeout: seconds the set-up (loading the FMUs, their probes) may take, compilers aside."""
        global _current
        self.channel, self.status = channel, channel.status
        self.step_timeout, self.setup_timeout, self.announce = step_timeout, setup_timeout, announce
        self.parts, self.current, self.labels, self.in_setup = [], None, {}, False
        self._rescue_r, self._rescue_w = os.pipe()
        guard.arm(self.status.fault, self._rescue_w)
        fmicall.trace_calls(self.status)
        threading.Thread(target=self._rescue, name="wavecosim-rescue", daemon=True).start()
        self.status.heartbeat = time.monotonic()        # the first beat: a call that holds the interpreter
        threading.Thread(target=self._watchdog, name="wavecosim-watchdog", daemon=True).start()   # from the start
        _current = self

    def close(self):
        """The run is over: faults are the process's own again."""
        global _current
        guard.disarm()
        fmicall.trace_calls(None)
        _current = None

    # ---- what the runner tells ----
    def watch(self, live, ref=None):
        """The runs to finish on a fault (the run, and its lockstep reference); their FMU binaries and
        output files go into the channel, for the parent."""
        self.parts = [p for p in (ref, live) if p is not None]
        self.labels = {id(live): "", **({id(ref): " (monolithic reference)"} if ref is not None else {})}
        self.channel.write_layout(self._layout())
        self.status.state = RUNNING

    def active(self, part):
        """`part` makes the next steps (an FMU fault is in its subsystems)."""
        self.current = part

    def _layout(self):
        parts = []
        for part in self.parts:
            files = {kind: str(part.out_dir / f"{kind}{part.suffix}.csv") for kind in ("trajectory", "steps")
                     if part.out_dir is not None}
            parts.append({"label": part.label, "suffix": part.suffix, "out_dir": str(part.out_dir or ""),
                          "scenario": part.scenario.name, "master": part.scenario.master.algorithm,
                          "K": part.scenario.master.K, "dt": part.dt, "T": part.scenario.T,
                          "reference": bool(self.labels.get(id(part))), "files": files,
                          "subsystems": {s.name: str(s.fmu.folder) for s in _fmus(part)}})
        return {"parts": parts, "libraries": self.libraries(),
                "components": {str(c): label for c, label in self.components().items()}}

    def libraries(self):
        """The FMU binaries this process has loaded: path, address range and fmi entry points."""
        return guard.fmu_libraries(FMI_ENTRIES)

    # ---- the watchdog ----
    def _progress(self):
        part = self.current
        if part is None:
            return None
        return id(part), part.steps_done, part.step_in_progress()

    def _limit(self):
        """The seconds the run may go without progress now (None: no limit); after a stop (Ctrl-C,
        SIGTERM) at most STOP_GRACE_S: a call that holds the signals is then taken as a timeout is."""
        limit = self.setup_timeout if self.status.state == SETUP else self.step_timeout
        if self.status.request in (STOP, TERM):
            return min(limit or STOP_GRACE_S, STOP_GRACE_S)
        return limit

    def _watchdog(self):
        """Beat for the parent; ask for a rescue when the run makes no progress within its timeout (the
        set-up timeout, compilers aside, then the step timeout)."""
        limits = [t for t in (self.step_timeout, self.setup_timeout) if t]
        poll = min([0.25] + [t / POLLS_PER_TIMEOUT for t in limits])
        last, since, tries = None, time.monotonic(), [0, 0]
        while True:
            time.sleep(poll)
            now = time.monotonic()
            self.status.heartbeat = now
            key = self._progress()
            limit = self._limit()
            if key != last or (self.status.state == SETUP and _compiling()):
                last, since, tries = key, now, [0, 0]
                continue
            if limit is None or now - since < limit or self.status.state == RESCUING:
                continue
            if self._ask_freeze(poll, tries):
                return

    def _ask_freeze(self, poll, tries):
        """One request to the main thread to park for the rescue; True once a fault is recorded. tries
        counts the requests it declined (it runs Python: interrupted there, unless a stop came, which
        it takes between two steps) and those nobody took."""
        self.in_setup = self.status.state == SETUP
        stopping = self.status.request in (STOP, TERM)
        if not stopping:
            self.status.request = TIMEOUT
        declined = self.status.fault.declined
        if not guard.freeze_main():
            return False
        time.sleep(poll)
        if self.status.fault.kind:
            return True
        if self.status.fault.declined > declined:
            if stopping:
                return False
            tries[0] += 1
            if tries[0] >= DECLINED_TRIES:
                guard.raise_in_main(PythonTimeout)
            return False
        tries[1] += 1
        return tries[1] >= UNANSWERED_TRIES and guard.claim_frozen()

    # ---- the rescue ----
    def _rescue(self):
        """Wait for a fault; then finish every run, print one line and end the process. A pipe closed
        under it (an FMU closed every descriptor, the process's output files with them) leaves the
        fault to the parent, which writes the rows from their shared memory."""
        if not os.read(self._rescue_r, 1):
            return
        self.in_setup = self.in_setup or self.status.state == SETUP
        self.status.state = RESCUING
        fault = self.status.fault.summary() or {}
        code = 1
        try:
            crashed = self.current
            if crashed is not None:
                crashed.salvage()
            error = self.error(fault)
            if crashed is not None and self.labels.get(id(crashed)):
                crashed.rescue(error)                    # the reference's files first
                self._catch_up(crashed)
            for part in self.parts:
                if part is not crashed or not self.labels.get(id(crashed)):
                    part.rescue(error)
            if self.announce:
                print(announcement(error), file=sys.stderr, flush=True)
            code = error.exit_code
        except BaseException as exc:                         # the rescue must end the process anyway
            print(f"error: the run stopped ({fault.get('kind')}) and could not be written whole: "
                  f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        self.status.exit_code, self.status.state = code, DONE
        flush_streams()
        os._exit(code)

    def _catch_up(self, reference):
        """After a fault in the lockstep reference (which runs ahead): the run makes the steps the
        reference made, so both end at the step that faulted. Its rows so far are written first: a
        second fault on the way loses nothing already computed."""
        live = next((p for p in self.parts if p is not reference), None)
        if live is None:
            return
        live.hand_over()
        self.current = live
        try:
            live.catch_up(reference.steps_done)
        except Exception:                                 # the run's own failure ends the catch-up
            pass

    def error(self, fault):
        """The exception that describes a fault (its class gives the exit code)."""
        part = self.current
        order = [p for p in self.parts if p is not part] + ([part] if part is not None else [])
        where = locate(fault.get("pc", []), self.libraries(),       # a binary both runs share: the active one's
                       {k: v for p in order for k, v in self._subsystems(p).items()})
        where = in_progress(where, fmicall.call_now(self.status), self.components())
        step = part.steps_done if part is not None else None
        t = part.t0 + step * part.dt if part is not None else None
        return describe(fault, self.status.request, where, step, t, self.step_timeout,
                        self.setup_timeout if self.in_setup else None)

    def components(self):
        """{component: subsystem label} of every FMU instance of the runs (the call in progress names one)."""
        return {s.fmu.component: f"{s.name}{self.labels.get(id(p), '')}" for p in self.parts for s in _fmus(p)
                if s.fmu.component}

    def _subsystems(self, part):
        return {str(s.fmu.folder): f"{s.name}{self.labels.get(id(part), '')}" for s in _fmus(part)}


def _compiling():
    """Whether this process has a child of its own now (a compiler building the kernel or an FMU)."""
    try:
        return any(p.read_text().strip() for p in Path("/proc/self/task").glob("*/children"))
    except OSError:
        return False


def flush_streams():
    """Flush stdout and stderr before the process ends with os._exit (a closed pipe is no error)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:
            pass


class PythonTimeout(StepTimeout):
    """A step that ran past the step timeout in Python code (raised there by the watchdog)."""

    def __init__(self):
        super().__init__("a macro-step did not finish within the step timeout (stopped in Python code)")


def announcement(error):
    """The one line a stopped run prints (as the command line does for the same error)."""
    if isinstance(error, Interrupted):
        return f"interrupted: {error}; results so far are on disk"
    return f"error: {error}"


def _fmus(part):
    scene = getattr(part, "scene", None)
    return [] if scene is None else [s for s in scene.subsystems + scene.signal_only if s.fmu is not None]
