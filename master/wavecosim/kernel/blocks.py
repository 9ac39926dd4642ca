"""The runner's per-block arithmetic over the C kernel's log (kernel/c/blocks.c, built into
the kernel library libblocks.so): the rows of a block of macro-steps (block_rows_steps), Condition 2
over it (passivity_steps) and the freeze watch (freeze_steps), which the kernel makes as it logs the
steps (Pass), and the certificates' columns (sampled_block, watch_block), each bit for bit the
step-by-step Python's. Without a C compiler
the library is missing, `library()` is None and the runner goes step by step (as it must anyway:
the kernel needs the compiler too)."""
import ctypes

from .abi import mirrors
from .build import helper_library
from .cvalues import ints  # noqa: F401  (the C int arrays of the passes' arguments)

PASSES = ("block_rows_steps", "passivity_steps", "freeze_steps")      # blocks.c's DRPassFns
_lib = None
_int_p, _double_p = ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_double)


@mirrors("blocks", "PassBlock")
class PassBlock(ctypes.Structure):
    """blocks.c: passivity_steps' arguments (the log's rows read, the block's columns written, the figures)."""
    _fields_ = [("k", ctypes.c_int), ("wave", ctypes.c_int), ("dt", ctypes.c_double), ("out", ctypes.c_void_p),
                ("ldo", ctypes.c_long), *[(name, _int_p) for name in ("port", "a", "b", "e", "f", "h")],
                ("prev", _double_p), ("fig", _double_p), ("has_h", _int_p), ("ledger", _double_p)]


@mirrors("blocks", "BlockRows")
class BlockRows(ctypes.Structure):
    """blocks.c: block_rows_steps' arguments (grid, log rows, the block's steps' and trajectory's columns,
    the run's iterations so far, where a durable run's rows are counted)."""
    _fields_ = [("n_out", ctypes.c_int), ("inverse", ctypes.c_double),
                ("dt", ctypes.c_double), ("outputs", _int_p), ("steps", ctypes.c_void_p), ("lds", ctypes.c_long),
                ("trajectory", ctypes.c_void_p), ("ldt", ctypes.c_long),
                ("iterations_sum", ctypes.c_double), ("iterations_max", ctypes.c_double), ("t0", ctypes.c_double),
                ("counted", ctypes.c_void_p * 2), ("base", ctypes.c_long * 2)]


@mirrors("blocks", "FreezeBlock")
class FreezeBlock(ctypes.Structure):
    """blocks.c: freeze_steps' arguments (the log's rows of the values watched, each subsystem's outputs
    and inputs among them, the watch's state)."""
    _fields_ = [*[(name, ctypes.c_int) for name in ("k", "frozen_steps", "n_values")],
                *[(name, _int_p) for name in ("rows", "out_at", "outs", "in_at", "ins")], ("last", _double_p),
                *[(name, _int_p) for name in ("count", "since", "found_from", "found_steps", "found_at",
                                              "first_from", "found_count")]]


@mirrors("blocks", "SampledBlock")
class SampledBlock(ctypes.Structure):
    """blocks.c: one block for sampled_block (CertificateSampler's columns and running figures)."""
    _fields_ = [*[(name, ctypes.c_int) for name in ("count", "k", "n", "nb", "first", "every", "fne", "augmented",
                                                    "rounds")],
                ("log", ctypes.c_void_p), ("ld", ctypes.c_long), ("certs", ctypes.c_void_p), ("ldc", ctypes.c_long),
                ("out", ctypes.c_void_p), ("ldo", ctypes.c_long), *[(name, _int_p) for name in ("a", "b", "h")],
                *[(name, _double_p) for name in ("min_fne", "max_aug", "H_prev")]]


@mirrors("blocks", "WatchBlock")
class WatchBlock(ctypes.Structure):
    """blocks.c: one block for watch_block (FneWatch's column and running figures)."""
    _fields_ = [*[(name, ctypes.c_int) for name in ("count", "k", "first", "every")], ("tol", ctypes.c_double),
                ("certs", ctypes.c_void_p), ("ldc", ctypes.c_long), ("out", ctypes.c_void_p),
                ("min_margin", _double_p), ("probed", ctypes.c_long)]


def library():
    """libblocks, built on first use; None when it cannot be built."""
    global _lib
    if _lib is None:
        _lib = helper_library("blocks")
    return _lib


class Pass:
    """One of the passes (PASSES) with its arguments: `steps(n0, log, first, count)` makes it from Python
    over steps first .. first + count - 1 of the block from macro-step n0 (`log`: its BlockLog);
    `function` is its address for the kernel to make it as the steps are logged (drkernel.h, DRPassFn)."""

    def __init__(self, name, args):
        self.args, self.ref = args, ctypes.byref(args)
        self.call = getattr(library(), name)
        self.function = ctypes.cast(self.call, ctypes.c_void_p).value

    def steps(self, n0, log, first, count):
        self.call(self.ref, n0, log.address, log.ld, first, count)


def columns(array):
    """(address, doubles between columns) of a 2-D float array whose columns are contiguous."""
    if array.strides[0] != 8:
        raise ValueError("blocks: a column's values must be contiguous")
    return array.ctypes.data, array.strides[1] // 8
