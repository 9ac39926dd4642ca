"""The output folder of a command while it writes: one writer at a time, and no stale file of an earlier
run left beside the new ones.

    with OutputFolder(out, overwrite=False):      # locked; an earlier run's files removed
        ...write...

A folder that holds files no wavecosim command writes is refused (OutputError, one line) unless
`overwrite`, which leaves those files alone. The lock is an advisory lock (flock) on OUT/.wavecosim.lock,
released with the process however it ends, and the file is removed after the run.
"""
import errno
import fcntl
import os
import re
from pathlib import Path

from ..errors import OutputError

LOCK = ".wavecosim.lock"
RUN_FILE = re.compile(r"^(?:(?:trajectory|steps|summary|metadata|fmu_log)(?:_[^/]+)?\.(?:csv|json|mat|txt)"
                      r"|[^/]+\.png|compare\.json|runs\.(?:csv|json)|row\.json|[^/]+\.part\d*)$")


def is_run_file(path: Path) -> bool:
    """A file one of wavecosim's commands writes into its output folder."""
    return path.is_file() and RUN_FILE.match(path.name) is not None


def cannot(path, exc, what="write"):
    """The OutputError for an OSError on `path`, in one line."""
    reason = exc.strerror or str(exc) if isinstance(exc, OSError) else str(exc)
    return OutputError(f"{path}: cannot {what}: {reason}")


_held = set()                 # folders this process (or the parent it was forked from) holds


class OutputFolder:
    """A command's output folder, locked and cleared of an earlier run's files (see the module)."""

    def __init__(self, path, overwrite=False, clear=True):
        """clear: refuse other files and remove an earlier run's (a general sweep, which resumes, only
        locks). A folder this process already holds (a supervised child's) is left as it is."""
        self.path, self.fd = Path(path), None
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise OutputError(f"{self.path}: is a file, not a folder; choose another --out") from None
        except OSError as exc:
            raise cannot(self.path, exc, "create the output folder") from None
        self.key = str(self.path.resolve())
        if self.key in _held:
            return
        self._lock()
        try:
            if clear:
                self._clear(overwrite)
        except BaseException:
            self.release()
            raise
        _held.add(self.key)

    def _lock(self):
        """Hold OUT/.wavecosim.lock (the same file another run would find: it is made again when a run
        removed it between our open and our lock)."""
        lock = self.path / LOCK
        for _ in range(10):
            try:
                fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise cannot(self.path, exc) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = _read(fd)
                os.close(fd)
                if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                    raise OutputError(f"{self.path}: another run is writing into this folder"
                                      f"{f' (process {holder})' if holder else ''}; wait for it or choose another "
                                      f"--out") from None
                raise cannot(self.path, exc) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(lock).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                self.fd = fd
                return
            os.close(fd)
        raise OutputError(f"{self.path}: could not lock the folder")

    def _clear(self, overwrite):
        entries = [p for p in self.path.iterdir() if p.name != LOCK]
        foreign = [p for p in entries if not is_run_file(p)]
        if foreign and not overwrite:
            names = ", ".join(sorted(p.name + ("/" if p.is_dir() else "") for p in foreign)[:5])
            more = f" and {len(foreign) - 5} more" if len(foreign) > 5 else ""
            raise OutputError(f"{self.path}: holds files that are not a wavecosim run's ({names}{more}); "
                              f"choose another --out, or pass --overwrite to write beside them")
        remove_run_files(self.path)

    def release(self):
        """Remove the lock file and let go of the lock."""
        if self.fd is None:
            return
        _held.discard(self.key)
        try:
            os.unlink(self.path / LOCK)
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()
        return False


def remove_run_files(folder):
    """Remove the files an earlier run wrote into `folder` (a new run replaces them wholly)."""
    for p in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if is_run_file(p):
            try:
                p.unlink()
            except OSError as exc:
                raise cannot(p, exc, "replace") from None


def _read(fd):
    try:
        return os.pread(fd, 32, 0).decode().strip()
    except (OSError, UnicodeDecodeError):
        return ""
