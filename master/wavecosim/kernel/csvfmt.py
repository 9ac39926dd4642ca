"""CSV text of a block of rows in one call into C (kernel/c/csvfmt.c, built into
the kernel library libcsvfmt.so): each float exactly as Python's repr writes it, integer and label columns as
the recorder's formatters do, so a file is byte for byte what the Python formatters would write.
Without a C compiler the library is missing and `block_writer` returns None (the recorder then
formats in Python)."""
import ctypes
import threading

import numpy as np

from .build import helper_library

_lib = None
_loading = threading.Lock()                # csv_init fills tables that no formatting may read half-filled
WIDTH = 26                    # at most 25 characters of repr (e.g. -2.2250738585072014e-308) and a comma
SLACK = 64                    # the C formatter stores digits in whole words, up to this far past the text


def library():
    """libcsvfmt, built on first use; None when it cannot be built."""
    with _loading:
        return _lib or _load()


def _load():
    """Load the library and fill its tables (once)."""
    global _lib
    lib = helper_library("csvfmt")
    if lib is not None:
        lib.csv_init()
        _lib = lib
    return _lib


def c_reprs(values):
    """repr of every float of a 1-D array, through the C formatter (for the checks against repr)."""
    values = np.ascontiguousarray(values, dtype=float)
    out = ctypes.create_string_buffer(len(values) * WIDTH + SLACK)
    n = library().csv_lines(values.ctypes.data, len(values), out)
    return out.raw[:n].decode().split("\n")[:-1]


class BlockWriter:
    """Writes rows of one column-major block (rows x columns, float64, order F) as CSV lines.
    kinds: per column 0 (float), 1 (integer) or a list of label names."""

    def __init__(self, lib, block, kinds):
        self.lib, self.block = lib, block
        labels = [k for k in kinds if isinstance(k, list)]
        names = [name.encode() for k in labels for name in k]
        starts, at = [], 0
        for k in kinds:
            starts.append(at if isinstance(k, list) else 0)
            at += len(k) if isinstance(k, list) else 0
        cols = len(kinds)
        self.kinds = (ctypes.c_int * cols)(*[2 if isinstance(k, list) else k for k in kinds])
        self.starts = (ctypes.c_int * cols)(*starts)
        self.names = (ctypes.c_char_p * max(1, len(names)))(*names)
        longest = sum(max(len(name.encode()) for name in k) for k in labels)     # label columns beyond WIDTH at most
        self.stride = cols * WIDTH + 2 + longest + SLACK      # text room per row: rows from `start` write from start * stride
        self.out = ctypes.create_string_buffer(block.shape[0] * self.stride)

    def __call__(self, rows, start=0):
        """Rows start .. start + rows - 1 of the block as bytes (ctypes lets go of the GIL meanwhile: a
        writer thread formats while the runner goes on; pieces of one block at different `start` use
        disjoint parts of the text buffer, so two threads may format them at once)."""
        out = ctypes.addressof(self.out) + start * self.stride
        n = self.lib.csv_rows(self.block.ctypes.data + 8 * start, self.block.strides[1] // 8, rows, self.block.shape[1],
                              self.kinds, self.names, self.starts, out)
        if n < 0:
            raise MemoryError("out of memory while formatting CSV rows")
        return ctypes.string_at(out, n)


def block_writer(block, kinds):
    """A BlockWriter for `block`, or None when the C formatter is not available or a kind is unknown."""
    lib = library()
    if lib is None or any(k is None for k in kinds):
        return None
    return BlockWriter(lib, block, kinds)
