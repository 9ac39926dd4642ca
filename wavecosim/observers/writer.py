"""CSV rows written off the runner's thread: a table hands over a block of rows and goes on filling
its other block, while a shared pool of threads formats the rows (the C formatter lets go of the
GIL) in pieces at once and appends the pieces to the file in the order they were handed over. The
first error of a writer (disk full, out of memory) is raised again, the same exception, by the
table's next hand-over or wait."""
import threading
from concurrent import futures
from concurrent.futures import ThreadPoolExecutor

from ..fast_path import available_cpus

SPLIT_ROWS = 128                 # rows handed over at once from which they are formatted in two pieces

_pool = None
_pool_lock = threading.Lock()


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


class Writer:
    """Appends text to one open file, piece after piece in the order handed over."""

    def __init__(self, file):
        self.file, self.last = file, None

    def hand_over(self, text, rows):
        """Write text(start, stop) of rows 0 .. rows - 1 (formatted in two pieces at once when there are
        many and two threads); returns the future of the last piece (done: all of them written)."""
        self.check()
        pieces = 2 if rows >= SPLIT_ROWS and threads() > 1 else 1
        bounds = [rows * k // pieces for k in range(pieces + 1)]
        for start, stop in zip(bounds, bounds[1:]):
            self.last = pool().submit(self._piece, text, start, stop, self.last)
        return self.last

    def _piece(self, text, start, stop, before):
        """Format, then write after the piece before (FIFO pool: that one has started already)."""
        data = text(start, stop)
        if before is not None:
            before.result()
        self.file.write(data)
        self.file.flush()

    def check(self):
        """Raise a finished writer's error, if any."""
        if self.last is not None and self.last.done() and self.last.exception() is not None:
            raise self.last.exception()

    def wait(self):
        """Until every piece handed over is written; raises the first writer error."""
        if self.last is not None:
            self.last.result()

    def wait_quietly(self):
        """Until no piece is being written any more (the file may be closed then); raises nothing,
        says whether a piece failed."""
        if self.last is None:
            return False
        futures.wait([self.last])
        return self.last.exception() is not None
