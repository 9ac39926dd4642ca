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
"""
import codecs
import gc
import io
import os
import selectors
import signal
import sys
import tempfile
import time
from pathlib import Path

from ..kernel.guard import die_with_parent, freeze_signal, require
from .channel import Channel, DONE, RESCUING, RUNNING, STOP, TERM, TIMEOUT
from .containment import Containment, announcement, flush_streams

STOP_GRACE_S = 5.0        # after passing a stop on: time for the child to stop between two steps
RESCUE_GRACE_S = 20.0     # after asking for a rescue: time for the child to write its rows
HEARTBEAT_GRACE_S = 10.0  # a child whose watchdog is silent this long past the step timeout is stuck


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

    def __init__(self, body, summary=None, step_timeout=None, relay=True, announce=True):
        """relay: the child's Python output comes back through this process's streams (else it
        writes to the inherited descriptors); announce: the error line of a fault is printed."""
        require()
        self.summary_path = Path(summary) if summary is not None else None
        self.step_timeout, self.announce, self.error = step_timeout, announce, None
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
            for r, _ in pipes:
                os.close(r)
            _become_child(body, self.channel, step_timeout, announce,
                          [(w, s.isatty(), getattr(s, "encoding", None) or "utf-8") for (_, w), s in zip(pipes, streams)])
        gc.unfreeze()
        os.close(death_w)
        for _, w in pipes:
            os.close(w)
        self.channel.status.pid = self.pid
        self.selector = selectors.DefaultSelector()
        self.selector.register(death_r, selectors.EVENT_READ, None)
        for (r, _), stream in zip(pipes, streams):
            self.selector.register(r, selectors.EVENT_READ, (stream, codecs.getincrementaldecoder("utf-8")("replace")))
        self.death_r, self.ended, self.wait_status, self.code = death_r, False, None, None
        self.stop_at, self.rescue_at, self.killed = None, None, None

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
        self._deadlines(time.monotonic())
        return self.ended

    def _read(self, key):
        try:
            data = os.read(key.fd, 65536)
        except OSError:
            data = b""
        if key.data is None:                                 # the death pipe: EOF when the child ends
            if not data:
                self.ended = True
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
        if self.ended or status.state == DONE:
            return
        if status.state == RESCUING:
            self.rescue_at = self.rescue_at or now
        if self.rescue_at is not None:                        # a rescue that never ends is ended
            if now - self.rescue_at > RESCUE_GRACE_S:
                self.killed = self.killed or "the rescue did not finish"
                _kill(self.pid, signal.SIGKILL)
            return
        if self.stop_at is not None and now - self.stop_at > STOP_GRACE_S:
            self._ask_rescue(now)
        elif (self.step_timeout and status.state == RUNNING and status.heartbeat
              and now - status.heartbeat > self.step_timeout + HEARTBEAT_GRACE_S):
            status.request = TIMEOUT                          # the watchdog itself is stuck
            self.killed = "stuck holding the interpreter"
            _kill(self.pid, signal.SIGKILL)

    def _ask_rescue(self, now):
        """The child did not stop between two steps: it is inside a call; ask its rescue to write it all."""
        self.rescue_at = now
        _kill(self.pid, freeze_signal())

    def wait(self):
        """Until the child has ended; its exit code (the fault's when the parent had to write the summary)."""
        while not self.poll(0.2):
            pass
        return self.finish()

    def kill(self):
        """End the child now (the caller is stopping) and reap it."""
        if self.code is None:
            _kill(self.pid, signal.SIGKILL)
            self.finish()

    def finish(self):
        """After the end: drain the output, reap the child, the exit code; the channel is removed."""
        if self.code is None:
            self.code = self._finish()
        return self.code

    def _finish(self):
        deadline = time.monotonic() + 2.0                     # the child's last output: its pipes end with it
        while len(self.selector.get_map()) > 1 and time.monotonic() < deadline:
            for key, _ in self.selector.select(0.1):
                if key.data is not None:
                    self._read(key)
        _, self.wait_status = os.waitpid(self.pid, 0)
        try:
            status = self.channel.status
            if status.state == DONE:
                return status.exit_code
            return self._fallback()
        finally:
            self.selector.close()
            os.close(self.death_r)
            self.channel.remove()

    def _fallback(self):
        """The child died without finishing: the summary from the channel, one line, the exit code."""
        from .salvage import salvage
        error = salvage(self.channel, self.wait_status, self.summary_path, self.step_timeout, self.killed)
        self.error = str(error)
        if self.announce:
            print(announcement(error), file=sys.stderr, flush=True)
        return error.exit_code


def _kill(pid, signum):
    try:
        os.kill(pid, signum)
    except ProcessLookupError:
        pass


def _become_child(body, channel, step_timeout, announce, relays):
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
        signal.signal(signal.SIGTERM, _terminate)
        contain = Containment(channel, step_timeout, announce)
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


def supervise(body, summary=None, step_timeout=None):
    """Run body() in a supervised child; SIGINT and SIGTERM are passed on; returns the exit code."""
    with passing_stops([]) as stops:
        child = Child(body, summary=summary, step_timeout=step_timeout)
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
