"""CSV rows written off the runner's thread: a table hands over a block of rows and goes on filling
its other block, while a shared pool of threads formats the rows (the C formatter lets go of the
GIL) in pieces at once and appends the pieces to the file in the order they were handed over. A
thread that waits for the rows (the table's flush and close) formats pieces nobody has taken yet,
so a busy machine costs no more than formatting on the runner's thread. The first error of a
writer (disk full, out of memory) is raised again, the same exception, by the table's next
hand-over or wait, and nothing after it is written."""
import functools
import threading
from collections import deque
from concurrent.futures import ThreadPoolExecutor

from ..fast_path import available_cpus

SPLIT_ROWS = 128                 # rows handed over at once from which they are formatted in two pieces

_pool = None
_pool_lock = threading.Lock()


@functools.cache
def threads():
    """How many writer threads: as many as CPUs, at most 2."""
    return max(1, min(2, available_cpus()))


def pool():
    """The writer threads of the process, made on first use."""
    global _pool
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(threads(), thread_name_prefix="csv-writer")
        return _pool


class Piece:
    """Rows start .. stop - 1 to format with text(start, stop); data: their bytes (or the exception
    formatting raised) once formatted, None before."""
    __slots__ = ("text", "start", "stop", "data")

    def __init__(self, text, start, stop):
        self.text, self.start, self.stop, self.data = text, start, stop, None


class Writer:
    """Appends text to one open file, piece after piece in the order handed over."""

    def __init__(self, file):
        self.file, self.error = file, None
        self.todo, self.unwritten = deque(), deque()      # pieces nobody has taken; pieces not yet written
        self.lock = threading.Lock()
        self.changed = threading.Condition(self.lock)     # a piece formatted or written
        self.writing = threading.Lock()                   # one thread at a time appends to the file

    def hand_over(self, text, rows):
        """Write text(start, stop) of rows 0 .. rows - 1 (in two pieces formatted at once when there are
        many and two threads); returns the pieces (see settle)."""
        self.check()
        count = 2 if rows >= SPLIT_ROWS and threads() > 1 else 1
        bounds = [rows * k // count for k in range(count + 1)]
        pieces = [Piece(text, start, stop) for start, stop in zip(bounds, bounds[1:])]
        with self.lock:
            self.todo.extend(pieces)
            self.unwritten.extend(pieces)
        for _ in pieces:
            pool().submit(self.work)
        return pieces

    def work(self):
        """Format the first piece nobody has taken (False: there is none), then write what is ready."""
        with self.lock:
            if not self.todo:
                return False
            piece = self.todo.popleft()
        try:
            data = piece.text(piece.start, piece.stop)
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
                    except BaseException as exc:
                        self.error = exc
                with self.lock:
                    self.unwritten.popleft()
                    piece.data = b""
                    self.changed.notify_all()

    def settle(self, pieces):
        """Until `pieces` are formatted (their block may then be filled again), helping meanwhile."""
        while any(p.data is None for p in pieces):
            if not self.work():
                with self.lock:
                    self.changed.wait_for(lambda: all(p.data is not None for p in pieces))

    def check(self):
        """Raise the writer's error, if any."""
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
