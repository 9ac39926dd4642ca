"""CSV rows written off the runner's thread: a table hands over a block of rows and goes on filling
its other block, while a shared pool of threads formats the rows (the C formatter lets go of the
GIL; two tables' blocks at once) and appends them to the file in the order they were handed over.
A thread that waits for the rows (the table's flush and close) formats a block nobody has taken
yet, so a busy machine costs little more than formatting on the runner's thread. The first error
of a writer (disk full, out of memory) is raised again, the same exception, by the table's next
hand-over or wait, and nothing after it is written."""
import os
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor

from ..errors import OutputError
from ..kernel.drkernel import available_cpus

_pool = None
_pool_lock = threading.Lock()


def _forget_pool():
    """In a forked child (a process pool's worker) the parent's threads do not exist: start afresh."""
    global _pool, _pool_lock
    _pool, _pool_lock = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def pool():
    """The writer threads of the process (as many as CPUs, at most 2: a run has two tables), made on
    first use."""
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max(1, min(2, available_cpus())), thread_name_prefix="csv-writer")
        return _pool


class Piece:
    """The first `rows` rows of a block, to format with text(rows); data: their bytes (or the
    exception formatting raised) once formatted, None before."""
    __slots__ = ("text", "rows", "data")

    def __init__(self, text, rows):
        self.text, self.rows, self.data = text, rows, None


class Writer:
    """Appends text to one open file, piece after piece in the order handed over; a durable table's
    writer tells its shared record (run/durable.py) the rows and bytes in the file after each piece."""

    def __init__(self, file, shared=None):
        self.file, self.error, self.shared = file, None, shared
        self.written = file.tell()                        # bytes of whole pieces in the file
        self.rows = 0                                     # rows of those pieces
        self.todo, self.unwritten = deque(), deque()      # pieces nobody has taken; pieces not yet written
        self.lock = threading.Lock()
        self.changed = threading.Condition(self.lock)     # a piece formatted or written
        self.writing = threading.Lock()                   # one thread at a time appends to the file

    def hand_over(self, text, rows):
        """Write text(rows), the first `rows` rows of a block, after what was handed over before;
        returns the Piece (see settle)."""
        self.check()
        piece = Piece(text, rows)
        with self.lock:
            self.todo.append(piece)
            self.unwritten.append(piece)
        pool().submit(self.work)
        return piece

    def work(self):
        """Format the first piece nobody has taken (False: there is none), then write what is ready."""
        with self.lock:
            if not self.todo:
                return False
            piece = self.todo.popleft()
        try:
            data = piece.text(piece.rows)
        except BaseException as exc:             # raised again by the table's next flush or close
            data = exc
        with self.lock:
            piece.data = data
            self.changed.notify_all()
        self._write_ready()
        return True

    def _write_ready(self):
        """Append the formatted pieces at the head of the queue to the file (after an error: drop them)."""
        with self.writing:
            while True:
                with self.lock:
                    if not self.unwritten or self.unwritten[0].data is None:
                        return
                    piece = self.unwritten[0]
                if self.error is None:
                    try:
                        if isinstance(piece.data, BaseException):
                            raise piece.data
                        self.file.write(piece.data)
                        self.file.flush()
                        self.written += len(piece.data)
                        self.rows += piece.rows
                        if self.shared is not None:
                            self.shared.wrote(self.rows, self.written)
                    except BaseException as exc:
                        self.error = exc
                with self.lock:
                    self.unwritten.popleft()
                    piece.data = b""
                    self.changed.notify_all()

    def settle(self, piece, written=False):
        """Until `piece` is formatted (its block may then be filled again), or written (or dropped after
        an error) when `written`, helping meanwhile."""
        done = (lambda: piece.data == b"") if written else (lambda: piece.data is not None)
        while not done():
            if not self.work():
                with self.lock:
                    self.changed.wait_for(done)

    def check(self):
        """Raise the writer's error, if any (an OSError as the OutputError naming the file)."""
        if isinstance(self.error, OSError):
            failure = OutputError(f"{self.file.name}: cannot write: {self.error.strerror or self.error}")
            failure.__cause__, self.error = self.error, failure
        if self.error is not None:
            raise self.error

    def wait(self):
        """Until every piece handed over is written (helping meanwhile); raises the writer's error."""
        self.wait_quietly()
        self.check()

    def wait_quietly(self):
        """As wait, raising nothing (the file may be closed then); says whether there was an error."""
        while self.work():
            pass
        with self.lock:
            self.changed.wait_for(lambda: not self.unwritten)
        return self.error is not None
