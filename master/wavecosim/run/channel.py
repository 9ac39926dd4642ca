"""The status channel of a supervised run: a folder the parent makes (run/supervisor.py) and the child
writes into (run/containment.py).

    <tmp>/wavecosim-run-XXXX/status       one page shared by both: state, exit code, the parent's
                                          request, the watchdog's heartbeat, guard.c's fault record
    <tmp>/wavecosim-run-XXXX/layout.json  the child's runs (output files) and FMU binaries (address
                                          ranges, entry points), written once set-up is done
    <tmp>/wavecosim-run-XXXX/tmp/         the child's temporary folder (its extracted FMUs)
    <tmp>/wavecosim-run-XXXX/rows-XXXX/   a run's tables: their blocks and counts of rows, mapped by
                                          both (run/durable.py), and rows.json, what they hold

The parent removes the folder when the child has ended, whatever ended it: nothing is left in the
temporary folder. `locate` turns the fault's code addresses into the subsystem and the FMU call.
"""
import json
import mmap
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import FmuCrashed, Interrupted, StepTimeout, Terminated
from ..kernel.guard import RunStatus

SETUP, RUNNING, RESCUING, DONE = range(4)          # the child's state
NONE, TIMEOUT, STOP, TERM = range(4)               # what ended the run from outside (the parent, the watchdog)
STOP_GRACE_S = 5.0             # after a stop (Ctrl-C, SIGTERM): time for the run to stop between two steps
MAGIC = 0x57435354
PAGE = 4096


class Channel:
    """One run's channel folder and its mapped status page."""

    def __init__(self, folder: Path, create=False):
        self.folder = Path(folder)
        path = self.folder / "status"
        if create:
            path.write_bytes(bytes(PAGE))
        fd = os.open(path, os.O_RDWR)
        try:
            self._map = mmap.mmap(fd, PAGE)
        finally:
            os.close(fd)
        self.status = RunStatus.from_buffer(self._map)       # both processes map the same file
        if create:
            self.status.magic = MAGIC

    @classmethod
    def create(cls):
        """A fresh channel in the temporary folder, with the child's own temporary folder in it."""
        folder = Path(tempfile.mkdtemp(prefix="wavecosim-run-"))
        (folder / "tmp").mkdir()
        return cls(folder, create=True)

    @property
    def temp(self) -> Path:
        return self.folder / "tmp"

    def write_layout(self, layout):
        tmp = self.folder / "layout.json.part"
        tmp.write_text(json.dumps(layout))
        tmp.replace(self.folder / "layout.json")

    def layout(self):
        """The child's layout, or None when it wrote none (it ended during set-up)."""
        try:
            return json.loads((self.folder / "layout.json").read_text())
        except (OSError, ValueError):
            return None

    def remove(self):
        """Unmap the page and remove the folder (the child's extracted FMUs with it)."""
        del self.status
        try:
            self._map.close()
        except BufferError:               # a view is still held somewhere: the folder goes anyway
            pass
        shutil.rmtree(self.folder, ignore_errors=True)


def locate(pcs, libraries, subsystems):
    """(who, call) of a fault from its code addresses (innermost first): `who` names the subsystems
    whose FMU binary holds the innermost address inside any FMU ("subsystem B", "subsystems B, C
    (Same.so)"), `call` the fmi entry point the outermost address of that binary is in. subsystems
    maps an FMU's extraction folder to its subsystem's name. ("", "") when no FMU is on the stack."""
    def library_of(pc):
        for lib in libraries:
            if any(lo <= pc < hi for lo, hi in lib["ranges"]):
                return lib
        return None

    for k, pc in enumerate(pcs):
        lib = library_of(pc)
        if lib is None:
            continue
        outer = pc
        for later in pcs[k + 1:]:
            if library_of(later) is not lib:
                break
            outer = later
        call = _entry(lib["entries"], outer - (1 if outer != pcs[0] else 0))
        return _owner(lib["path"], subsystems), call
    return "", ""


def in_progress(where, call_now, components):
    """(who, call) of a fault, where a stack named no subsystem (none was taken: the FMU holds the
    freeze signal; or the set-up had named none yet), from the FMU call in progress the status page
    records: call_now = (instance, call, opening) (kernel/fmicall.py), components maps an FMU
    instance's component to its subsystem's name; before the runs have any (the set-up), the subsystem
    whose FMU the set-up opens. An instance no run knows (a shim's) names the call alone."""
    who, call = where
    instance, now, opening = call_now
    if not now or (who and not who.startswith("an FMU (")):
        return where
    name = components.get(instance) or ("" if components and instance else opening.split("~")[0])
    return (f"subsystem {name}" if name else who), call or now


def _entry(entries, pc):
    """The entry point whose code holds pc: the nearest one at or below it."""
    below = [(addr, name) for name, addr in entries.items() if addr is not None and addr <= pc]
    return max(below)[1] if below else ""


def _owner(path, subsystems):
    names = [name for folder, name in subsystems.items() if path.startswith(folder.rstrip("/") + "/")]
    if len(names) == 1:
        return f"subsystem {names[0]}"
    if names:
        return f"subsystems {', '.join(names)} ({Path(path).name})"
    return f"an FMU ({Path(path).name})"


def describe(fault, request, where, step, t, step_timeout, setup_timeout=None):
    """The FmuCrashed, StepTimeout or Interrupted for a fault record: what happened, in which
    subsystem and call (`where`, from locate), at which step (starting at time t); setup_timeout:
    the fault came during the set-up, which that timeout ended."""
    who, call = where
    at = "" if step is None else f" at step {step} (t = {t:.6g})"
    kind, call_text = fault.get("kind"), f" in {call}" if call else ""
    if kind == "signal" and who and fault.get("main_thread") is False:
        call_text = " in a thread it started"
    if request in (STOP, TERM) and kind in ("frozen", None, "none"):
        cls, verb = (Terminated, "stopped by SIGTERM") if request == TERM else (Interrupted, "interrupted by the user")
        return cls(f"{verb}{at}, inside {who}{call_text}" if who else f"{verb}{at}")
    held = "; the FMU holds the signal that would stop it" if kind == "frozen" and fault.get("code") == -1 else ""
    inside = (f"; stopped inside {who}{call_text}" if who else f"; stopped{call_text}" if call else "") + held
    if request == TIMEOUT and kind in ("frozen", None, "none") and setup_timeout:
        return StepTimeout(f"the set-up did not finish within {setup_timeout:g} s (set-up timeout){inside}")
    if request == TIMEOUT and kind in ("frozen", None, "none"):
        late = f"did not finish within {step_timeout:g} s (step timeout)" if step_timeout else "did not finish"
        return StepTimeout(f"step {step} (t = {t:.6g}) {late}{inside}" if step is not None
                           else f"a step {late}{inside}")
    if kind == "exit":
        happened = f"the FMU ended the process with exit({fault.get('code')})"
    else:
        name = fault.get("signal") or "a signal"
        happened = f"the FMU crashed ({name}: {_strsignal(name)})" if who else f"the run crashed ({name})"
    subject = f"{who}: " if who else ""
    return FmuCrashed(f"{subject}{happened}{call_text}{at}")


def _strsignal(name):
    import signal
    try:
        return (signal.strsignal(signal.Signals[name]) or name).lower()
    except (KeyError, ValueError):
        return name
