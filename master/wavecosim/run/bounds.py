"""Honest status: a run stops with a NumericalError naming the subsystem, the variable and the step
when a recorded output or a subsystem's stored energy is not finite, or when a recorded output
has grown past `growth_bound` (scenario key, default 1e12) times the outputs' initial scale: the
largest magnitude among the Real ones at the start, or 1 when that is smaller (outputs that start at rest). The
rows up to that step are kept. The C kernel's blocks stop after such a step too (Route.observe's
bound), so both routes make the same steps and FMU calls."""
import math

from ..errors import NumericalError
from ..fmi.values import REAL, category


class Bounds:
    """The checks of one run, set from its first reading (t = 0)."""

    def __init__(self, scene, outputs, growth, types):
        """outputs: {column: SUBSYSTEM.variable}, types: each column's FMI type (only Real columns
        have a growth bound; Integer, Boolean and text columns are recorded as they are)."""
        self.refs = [ref.split(".", 1) for ref in outputs.values()]
        self.real = [category(kind) == REAL for kind in types]
        self.energy = [(s.name, s.port.energy) for s in scene.subsystems]
        self.growth, self.time_of = growth, None
        self.scale, self.limit = 1.0, math.inf

    def start(self, reading, time_of):
        """Take the initial scale from the Real outputs at the start time (time_of(k): t_k) and check them."""
        self.time_of = time_of
        finite = [abs(x) for x, real in zip(reading.outputs, self.real) if real and math.isfinite(x)]
        self.scale = max(finite + [1.0])
        self.limit = self.growth * self.scale
        self.check(reading, -1)

    def bounded(self, rows):
        """Of the rows of the outputs (one per column), those of Real columns: what the kernel bounds."""
        return [row for row, real in zip(rows, self.real) if real]

    def _where(self, n):
        return (f"at t = {self.time_of(0):.6g} (the initial values)" if n < 0 else
                f"at step {n} (t = {self.time_of(n + 1):.6g})")

    def check(self, reading, n):
        """Raise the NumericalError of the first bad value after step n (-1: the initial values)."""
        for (sub, var), x in zip(self.refs, reading.outputs):
            if not math.isfinite(x):
                raise NumericalError(f"subsystem {sub}: {var} = {x} is not finite {self._where(n)}")
        for (sub, var), h in zip(self.energy, reading.H):
            if var is not None and not math.isfinite(h):
                raise NumericalError(f"subsystem {sub}: its stored energy {var} = {h} is not finite {self._where(n)}")
        for (sub, var), x, real in zip(self.refs, reading.outputs, self.real):
            if real and abs(x) > self.limit:
                raise NumericalError(f"subsystem {sub}: {var} = {x:.6g} {self._where(n)} has grown past "
                                     f"{self.limit:.3g} (growth_bound {self.growth:g} times the outputs' initial "
                                     f"scale {self.scale:.3g})")
