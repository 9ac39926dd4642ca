"""The parent of a supervised run: `wavecosim run` (and each run of a local sweep) makes its steps in a
child process, so an FMU that crashes, calls exit() or never returns cannot take the rows computed
so far, the summary or the exit code with it.

    child = Child(body, summary=out / "summary.json", step_timeout=5)
    code = child.wait()                       # the child's exit code, or the fault's

The child is forked (no second start-up of the interpreter) into a process group of its own: the
parent passes SIGINT and SIGTERM on, once, and the child stops as between two steps. Its Python
output comes back through pipes to the parent's streams (so a caller that captures them sees it).
When the child cannot finish by itself (it holds a stuck GIL, it was killed, a stop request found
it inside a call that does not return), the parent asks its rescue thread (run/containment.py)
and, failing that, ends it and writes summary.json from the status channel: the rows already in
the files, a last line cut by the death removed, the fault's subsystem, call and step.

The parent keeps its own watch, whatever the FMU does with signals: a child that stopped itself,
whose watchdog went silent, or that did not begin its rescue soon after it was asked is ended with
SIGKILL, its whole process group (helpers an FMU forked) with it. The child gets SIGTERM when the
parent dies; a janitor process (`sh`, started beside it) then ends what is left of its group and
removes the channel folder.
"""
import codecs
import gc
import io
import os
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ..kernel.fmicall import call_now
from ..kernel.guard import die_with_parent, freeze_signal, require, signal_name
from ..errors import FmuCrashed, Interrupted, StepTimeout, Terminated
from .channel import Channel, DONE, RESCUING, SETUP, STOP, STOP_GRACE_S, TERM, TIMEOUT, in_progress
from .containment import Containment, announcement, flush_streams

RESCUE_GRACE_S = 20.0     # once its rescue began: time for the child to write its rows
ASKED_GRACE_S = 3.0       # after a rescue was asked (by the parent or the child's watchdog): time for it to begin
HEARTBEAT_GRACE_S = 5.0   # a child whose watchdog is silent this long past its timeout is stuck
STOPPED_GRACE_S = 5.0     # a child stopped (SIGSTOP) with no timeout to wait for is ended after this long
_JANITORS = set()         # the janitors' stdin descriptors: no child holds one open
SETUP_TIMEOUT_S = 60.0    # the set-up timeout by default (`--setup-timeout`)
JANITOR = ("trap '' INT TERM HUP; read end; i=0; while kill -0 $2 2>/dev/null && [ $i -lt 50 ]; "
           "do sleep 0.1; i=$((i+1)); done; kill -KILL -$2 2>/dev/null; rm -rf \"$1\"")


class Relay(io.TextIOBase):
    """The child's sys.stdout or sys.stderr: text written to a pipe the parent reads."""

    def __init__(self, fd, tty, encoding):
        self.fd, self._tty, self._encoding = fd, tty, encoding

    def writable(self):
        return True

    def isatty(self):
        return self._tty

    @property
    def encoding(self):
        return self._encoding

    def write(self, text):
        data = text.encode(self._encoding, "replace")
        while data:
            try:
                data = data[os.write(self.fd, data):]
            except InterruptedError:
                continue
            except OSError:              # the parent is gone: nothing to tell
                return len(text)
        return len(text)

    def fileno(self):
        return self.fd


class Child:
    """One supervised child running body() (which returns its exit code)."""

    def __init__(self, body, summary=None, step_timeout=None, relay=True, announce=True,
                 setup_timeout=SETUP_TIMEOUT_S):
        """relay: the child's Python output comes back through this process's streams (else it
        writes to the inherited descriptors); announce: the error line of a fault is printed."""
        require()
        self.summary_path = Path(summary) if summary is not None else None
        self.step_timeout, self.setup_timeout = step_timeout, setup_timeout
        self.announce, self.error, self.cause = announce, None, None
        self.channel = Channel.create()
        streams = [sys.stdout, sys.stderr] if relay else []
        pipes = [os.pipe() for _ in streams]
        death_r, death_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        gc.freeze()                  # the child's collector leaves the objects it was born with alone: fewer pages copied
        self.pid = os.fork()
        if self.pid == 0:                                     # the child: never returns
            os.close(death_r)
            for fd in _JANITORS:
                os.close(fd)
            for r, _ in pipes:
                os.close(r)
            _become_child(body, self.channel, (step_timeout, setup_timeout), announce,
                          [(w, s.isatty(), getattr(s, "encoding", None) or "utf-8") for (_, w), s in zip(pipes, streams)])
        gc.unfreeze()
        os.close(death_w)
        for _, w in pipes:
            os.close(w)
        self.channel.status.pid = self.pid
        self.janitor = _janitor(self.channel.folder, self.pid)
        _JANITORS.add(self.janitor.stdin.fileno())
        self.selector = selectors.DefaultSelector()
        self.selector.register(death_r, selectors.EVENT_READ, None)
        for (r, _), stream in zip(pipes, streams):
            self.selector.register(r, selectors.EVENT_READ, (stream, codecs.getincrementaldecoder("utf-8")("replace")))
        self.death_r, self.ended, self.wait_status, self.code = death_r, False, None, None
        self.stop_at, self.rescue_at, self.asked_at, self.stopped_at = None, None, None, None

    # ---- the parent's loop ----
    def fileno(self):
        return self.death_r

    def stop(self, signum):
        """Pass a stop (SIGINT or SIGTERM) on; a second one is passed on too (the child then stops at once)."""
        if self.ended:
            return
        self.stop_at = self.stop_at or time.monotonic()
        self.channel.status.request = TERM if signum == signal.SIGTERM else STOP
        _kill(self.pid, signum)

    def poll(self, timeout=0.1):
        """Relay output, watch deadlines; True once the child has ended."""
        for key, _ in self.selector.select(timeout):
            self._read(key)
        self._reap()
        self._deadlines(time.monotonic())
        return self.ended

    def _reap(self):
        """Whether the child ended or stopped (its death pipe may stay open in a helper it forked)."""
        if self.wait_status is not None:
            return
        try:
            pid, status = os.waitpid(self.pid, os.WNOHANG | os.WUNTRACED)
        except ChildProcessError:
            pid, status = self.pid, 0
        if pid == 0:
            return
        if os.WIFSTOPPED(status):
            self.stopped_at = self.stopped_at or time.monotonic()
            return
        self.wait_status, self.ended = status, True

    def _read(self, key):
        try:
            data = os.read(key.fd, 65536)
        except OSError:
            data = b""
        if key.data is None:            # the death pipe: EOF when the child (and what it forked) closed it
            if not data:
                self.selector.unregister(key.fd)
            return
        stream, decoder = key.data
        if not data:
            self.selector.unregister(key.fd)
            os.close(key.fd)
            text = decoder.decode(b"", final=True)
        else:
            text = decoder.decode(data)
        if text:
            stream.write(text)
            stream.flush()

    def _deadlines(self, now):
        status = self.channel.status
        if self.ended or status.state == DONE or self.cause is not None:
            return
        if status.state == RESCUING:
            self.rescue_at = self.rescue_at or now
            if now - self.rescue_at > RESCUE_GRACE_S:               # a rescue that never ends is ended
                self._end(FmuCrashed, "the rescue did not finish")
            return
        if status.request == TIMEOUT:                               # the child's watchdog asked for a rescue
            self.asked_at = self.asked_at or now
        if self.asked_at is not None and now - self.asked_at > ASKED_GRACE_S:
            self._end(*self._overdue())
        elif self.stop_at is not None and self.asked_at is None and now - self.stop_at > STOP_GRACE_S:
            self.asked_at = now
            _kill(self.pid, freeze_signal())                        # inside a call: ask its rescue to write it all
        elif self._silent(status, now):
            self._end(*self._overdue(stuck=True))

    def _silent(self, status, now):
        """Whether the child stopped (SIGSTOP) or its watchdog went silent past its timeout."""
        limit = self.setup_timeout if status.state == SETUP else self.step_timeout
        if self.stopped_at is not None:
            if status.heartbeat > self.stopped_at:                  # it went on since (SIGCONT)
                self.stopped_at = None
            elif now - self.stopped_at > (limit or STOPPED_GRACE_S):
                return True
        return bool(limit and status.heartbeat and now - status.heartbeat > limit + HEARTBEAT_GRACE_S)

    def _overdue(self, stuck=False):
        """(error class, message) of a child ended because it did not answer in time."""
        status = self.channel.status
        why = ("it stopped itself (SIGSTOP)" if self.stopped_at is not None else
               "it went silent (stuck holding the interpreter)" if stuck else
               "the FMU holds the signals that would stop it") + self._inside()
        if self.stop_at is not None:
            cls = Terminated if status.request == TERM else Interrupted
            return cls, f"{'stopped by SIGTERM' if cls is Terminated else 'interrupted by the user'}; {why}, the child was ended"
        if status.state == SETUP:
            return StepTimeout, f"the set-up did not finish within {self.setup_timeout:g} s (set-up timeout); {why}"
        late = f"did not finish within {self.step_timeout:g} s (step timeout)" if self.step_timeout else "did not finish"
        return StepTimeout, f"a step {late}; {why}"

    def _inside(self):
        """` inside subsystem B in fmi2DoStep`: the FMU call in progress the status page records, if any."""
        components = {int(c): label for c, label in ((self.channel.layout() or {}).get("components") or {}).items()}
        who, call = in_progress(("", ""), call_now(self.channel.status), components)
        return f" inside {who} in {call}" if who and call else ""

    def _killed(self):
        """(FmuCrashed, message) for a child killed outright (it left no fault record: SIGKILL, the
        out-of-memory killer) inside an FMU call, naming the call; else None."""
        status = self.wait_status
        if self.channel.status.fault.kind or status is None or not os.WIFSIGNALED(status):
            return None
        inside = self._inside()
        return (FmuCrashed, f"the run crashed ({signal_name(os.WTERMSIG(status))}){inside}") if inside else None

    def _end(self, cls, message):
        """Kill the child's process group now; its summary says `message` (an error of class cls)."""
        self.cause = (cls, message)
        _kill_group(self.pid)

    def wait(self):
        """Until the child has ended; its exit code (the fault's when the parent had to write the summary)."""
        while not self.poll(0.2):
            pass
        return self.finish()

    def kill(self):
        """End the child now (the caller is stopping) and reap it."""
        if self.code is None:
            _kill_group(self.pid)
            self.finish()

    def finish(self):
        """After the end: drain the output, reap the child, the exit code; the channel is removed."""
        if self.code is None:
            self.code = self._finish()
        return self.code

    def _finish(self):
        if self.wait_status is None:
            _, self.wait_status = os.waitpid(self.pid, 0)
        _kill_group(self.pid)                                 # helpers an FMU forked end with it
        deadline = time.monotonic() + 2.0                     # the child's last output: its pipes end with it
        while _relaying(self.selector) and time.monotonic() < deadline:
            for key, _ in self.selector.select(0.1):
                if key.data is not None:
                    self._read(key)
        try:
            status = self.channel.status
            if status.state == DONE:
                from .salvage import complete_rows
                complete_rows(self.channel.folder)          # rows its writers could not write
                return status.exit_code
            return self._fallback()
        finally:
            for fd in list(self.selector.get_map()):          # pipes a helper of the child kept open
                if fd != self.death_r:
                    os.close(fd)
            self.selector.close()
            os.close(self.death_r)
            self.channel.remove()
            _JANITORS.discard(self.janitor.stdin.fileno())
            self.janitor.stdin.close()                        # it ends the group again, and goes
            self.janitor.wait()

    def _fallback(self):
        """The child died without finishing: the summary from the channel, one line, the exit code."""
        from .salvage import salvage
        error = salvage(self.channel, self.wait_status, self.summary_path, self.step_timeout,
                        self.cause or self._killed())
        self.error = str(error)
        if self.announce:
            print(announcement(error), file=sys.stderr, flush=True)
        return error.exit_code


def _kill(pid, signum):
    try:
        os.kill(pid, signum)
    except ProcessLookupError:
        pass


def _relaying(selector):
    """Whether any of the child's output pipes is still open."""
    return any(key.data is not None for key in selector.get_map().values())


def _kill_group(pid):
    """SIGKILL to the child's process group (it made one of its own): stopped, blocked or not."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _janitor(folder, pid):
    """A shell that waits for this process to end (its stdin closes), then for the child `pid` (which
    gets SIGTERM when this process dies) at most 5 s, kills what is left of the child's group and
    removes the channel folder: nothing outlives a parent killed outright."""
    return subprocess.Popen(["/bin/sh", "-c", JANITOR, "janitor", str(folder), str(pid)], stdin=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def _become_child(body, channel, timeouts, announce, relays):
    """In the forked child: own process group, die with the parent, relayed streams, the channel's
    temporary folder, containment armed; body(); never returns."""
    code = 1
    try:
        os.setpgid(0, 0)
        die_with_parent(signal.SIGTERM)
        if relays:
            sys.stdout, sys.stderr = (Relay(fd, tty, enc) for fd, tty, enc in relays)
        tempfile.tempdir = str(channel.temp)
        os.environ["TMPDIR"] = str(channel.temp)
        signal.signal(signal.SIGINT, signal.default_int_handler)    # a Dask worker's ignores it
        signal.signal(signal.SIGTERM, _terminate)
        contain = Containment(channel, timeouts[0], announce, timeouts[1])
        code = body()
        contain.close()
        channel.status.exit_code, channel.status.state = code, DONE
    except BaseException as exc:              # body() maps every error to its code; this is a bug
        print(f"error: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        channel.status.exit_code, channel.status.state = code, DONE
    finally:
        flush_streams()
        os._exit(code)


def _terminate(signum, frame):
    """SIGTERM in the child outside the steps (set-up): stop as Ctrl-C does."""
    raise KeyboardInterrupt


def supervise(body, summary=None, step_timeout=None, setup_timeout=SETUP_TIMEOUT_S):
    """Run body() in a supervised child; SIGINT and SIGTERM are passed on; returns the exit code."""
    with passing_stops([]) as stops:
        child = Child(body, summary=summary, step_timeout=step_timeout, setup_timeout=setup_timeout)
        stops.children.append(child)
        if stops.signal is not None:                     # it came while the child was being made
            child.stop(stops.signal)
        return child.wait()


class passing_stops:
    """SIGINT and SIGTERM go to the children (a list the caller keeps up to date) while they run, not
    to this process; `signal` is the first one that came."""

    def __init__(self, children):
        self.children, self.signal = children, None

    def __enter__(self):
        import threading
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._pass)
        return self

    def _pass(self, signum, frame):
        self.signal = self.signal or signum
        for child in self.children:
            child.stop(signum)

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        return False
