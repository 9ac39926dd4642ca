"""The sampled certificates inside the C kernel's blocks of macro-steps (kernel/c/certs.c): u*
by the interface Newton, the FNE margins on random pairs, the Fejer term of Theorem 1 and the
Condition 1 watch's secant margins, computed around each step of a block as the observers compute
them step by step (wavecosim/core/certificates.py, observers/fne_watch.py), to the last bit. The random
normals of a block's sampled steps are drawn up front from the observers' Generator, in the order
the step-by-step path draws them; the FMU calls go through a kernel of their own (not the master's).
"""
import ctypes

import numpy as np

from ..errors import FmuError
from .abi import mirrors
from .drkernel import load_library
from .fmicall import FUNCTION_NAMES
from .newton import NON_FINITE, NOT_CONVERGED, WHY, NewtonKernel, failed, nan_source, not_converged


@mirrors("drkernel", "DCSettings")
class DCSettings(ctypes.Structure):
    """certs.h: DCSettings."""
    _fields_ = [("every", ctypes.c_int), ("pairs", ctypes.c_int), ("augmented", ctypes.c_int),
                ("watch", ctypes.c_int), ("probe", ctypes.c_int), ("scale", ctypes.c_double),
                ("floor", ctypes.c_double), ("probe_rel", ctypes.c_double)]


def supports(scene):
    """Whether the kernel can compute the certificates of this scene (a description.KernelScene): every
    port is its FMU's own wave map (no adapter, no input scaling)."""
    return all(s.plain_wave for s in scene.subsystems)


class KernelCertificates:
    """The certificates' part of the master's block calls; CertificateSampler (sample) and FneWatch
    (watch) switch their parts on before the first block, then read `rows` after each block."""

    def __init__(self, kernel, newton: NewtonKernel, scene, floor):
        self.lib, self.kernel, self.newton, self.scene = load_library(), kernel, newton, scene
        self.subsystems = scene.subsystems
        self.settings = DCSettings(1, 0, 0, 0, 0, 0.0, floor, 0.0)
        self.stage_vr, self.gammas = None, np.empty(len(self.subsystems))
        self.rng, self.per_step, self.handle = None, 0, None
        self.chunks, self.start, self.last = [], 0, np.empty((0, 3 * len(self.subsystems) + 1))
        self.made = (0, self.last)                 # the steps of the last call and their rows

    def sample(self, pace, pairs, scale, rng, augmented):
        """u* and the Fejer term (augmented) and `pairs` FNE pairs per subsystem at the sampled steps."""
        s = self.settings
        s.every, s.pairs, s.scale, s.augmented = pace.every, pairs, scale, int(augmented)
        self.rng, self.per_step = rng, sum(2 * pairs * sub.m for sub in self.subsystems)

    def watch(self):
        """The secant margins of every step from the inner loop's trace."""
        self.settings.watch = 1

    def probe(self, pace, rel):
        """Instead, the watch's probe at the sampled steps (K < 2), where every port has one channel
        (scalar solve and eigenvalue); False where one has more."""
        if any(s.probe_vrs is None for s in self.subsystems):
            return False
        vrs = [vr for s in self.subsystems for vr in s.probe_vrs]
        self.stage_vr = (ctypes.c_uint * len(vrs))(*vrs)
        self.settings.probe, self.settings.every, self.settings.probe_rel = 1, pace.every, rel
        return True

    def create(self):
        """The C side, once configured (sample, watch, probe): in set-up, or at the first arm."""
        if self.handle is None:
            self.handle = self.lib.dc_create(self.kernel.handle, self.newton.handle, self.newton.base.handle,
                                              ctypes.byref(self.settings), self.stage_vr)
            if not self.handle:
                raise FmuError("the certificates' kernel could not be created (out of memory)")

    def arm(self, n0, count):
        """Before a kernel call of steps n0 .. n0 + count - 1: the normals of its sampled steps."""
        self.create()
        every = self.settings.every
        self.n0, self.sampled = n0, np.arange((-n0) % every, count, every)      # its sampled steps, from 0
        self.state = self.rng.bit_generator.state if self.rng is not None else None
        need = len(self.sampled) * self.per_step
        self.normals = self.rng.standard_normal(need) if need else np.zeros(1)
        self.rows = np.empty((count, 3 * len(self.subsystems) + 1))
        self.gammas[:] = self.scene.gammas()
        self.lib.dc_arm(self.handle, n0, self.normals.ctypes.data, self.rows.ctypes.data, self.gammas.ctypes.data)

    def disarm(self, done):
        """After the call that made `done` steps: keep their rows; the Generator stands after the
        normals of those steps; returns the certificates' own failure (an exception) or None."""
        self.lib.dc_arm(self.handle, 0, None, None, None)
        culprit, out, used = (ctypes.c_int * 3)(), (ctypes.c_double * 2)(), ctypes.c_long()
        rc = self.lib.dc_status(self.handle, culprit, out, ctypes.byref(used))
        kept = int(np.count_nonzero(self.sampled < done)) * self.per_step
        if kept < len(self.normals) and self.per_step:
            self.rng.bit_generator.state = self.state
            self.rng.standard_normal(kept)
        self.chunks.append((self.n0, self.rows[:done]))
        self.made = (self.n0, self.rows[:done])
        if not rc:
            return None
        n = self.n0 + done
        t, where = n * self.kernel.io.dt, f" at step {n} (t = {n * self.kernel.io.dt:.6g})"
        if rc < 0:
            sub = self.subsystems[culprit[0]]
            return sub.fmu.error(FUNCTION_NAMES.get(culprit[1]), culprit[2], n, t)
        if rc == NOT_CONVERGED:
            return not_converged(where, float(out[0]), float(out[1]))
        return failed(where, WHY[rc], nan_source(self.subsystems, int(out[1])) if WHY[rc] == NON_FINITE
                      else None)

    def block_rows(self, n0, count):
        """The rows of steps n0 .. n0 + count - 1 made in the kernel calls since the last block (fne per
        subsystem, Fejer term, watch margin per subsystem, watch pairs kept per subsystem)."""
        if self.chunks:
            self.start, self.last = self.chunks[0][0], np.concatenate([rows for _, rows in self.chunks])
            self.chunks = []
        return self.last[n0 - self.start:n0 - self.start + count]

    def row_of(self, n):
        """The row of step n if the last call made it (a step finished step by step after its block), else None."""
        n0, rows = self.made
        return rows[n - n0] if 0 <= n - n0 < len(rows) else None

    def close(self):
        if self.handle:
            self.lib.dc_destroy(self.handle)
            self.handle = None
