"""Honest status: a run stops with a NumericalError naming the subsystem, the variable and the step
when a recorded output or a subsystem's stored energy is not finite, or when a recorded output
has grown past `growth_bound` (scenario key, default 1e12) times the outputs' initial scale: the
largest magnitude among the Real ones at the start, or 1 when that is smaller (outputs that start at rest). The
rows up to that step are kept. The C kernel's blocks stop after such a step too (Route.observe's
bound), so both routes make the same steps and FMU calls."""
import math

from ..core.quirks import repeat_difference
from ..errors import FmuError, NumericalError, WavecosimError
from ..fmi.values import REAL, category

MAX_OUTPUTS = 64               # Real outputs of an FMU read when a step failed (to find a NaN it gave)
BROKEN_RESTORE = 1e-6          # a relative difference after fmi2SetFMUstate past this is a broken restore


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


def non_finite_outputs(scene):
    """[(subsystem, variable, value)] of the FMUs' Real outputs that are not finite at this point, read from
    every FMU still in its step phase (at most MAX_OUTPUTS outputs each)."""
    found = []
    for sub in scene.subsystems + scene.signal_only:
        fmu = sub.fmu
        names = [v.name for v in fmu.description.modelVariables if v.causality == "output"
                 and v.type == fmu.real_type and not getattr(v, "dimensions", None)][:MAX_OUTPUTS]
        if getattr(fmu, "phase", None) != "step" or not names:
            continue
        try:
            values = fmu.get_real(fmu.real_vrs(names))
        except WavecosimError:
            continue
        found += [(sub.name, name, float(x)) for name, x in zip(names, values) if not math.isfinite(x)]
    return found


def named_for_nan(scene, error):
    """The error of a failed step named for its cause when an FMU's outputs hold a NaN or an infinity:
    it reaches the master and the coupled subsystems first (as a non-finite residual, a singular
    Newton matrix, an input the other FMU refuses), so the error names a subsystem that only received
    it. A NumericalError naming the FMU that gave it, else `error` as it is."""
    if type(error) not in (FmuError, NumericalError):
        return error
    found, text = non_finite_outputs(scene), str(error)
    if not found or (f"subsystem {found[0][0]}" in text and "finite" in text):       # named already
        return error
    sub, var, value = found[0]
    return NumericalError(f"subsystem {sub}: its FMU gave a non-finite output, {var} = {value}, which stopped "
                          f"the run where it arrived: {error}")


def named_for_restore(scene, error):
    """An interface solve that did not converge, named for its cause when an FMU does not restore its
    state: the set-up probe found it (core/quirks.py: restore_difference past BROKEN_RESTORE), or the
    step made twice now from the saved state differs (a restore that broke during the run); its
    iterations then chase a moving target. The same NumericalError class, the FMU named; else `error`."""
    text = str(error)
    if not isinstance(error, NumericalError) or not ("no convergence" in text or "did not converge" in text):
        return error
    broken = sorted(((d.found.get("restore_difference") or 0.0, name) for name, d in scene.decisions.items()
                     if (d.found.get("restore_difference") or 0.0) > BROKEN_RESTORE), reverse=True)
    if broken:
        difference, name = broken[0]
        return NumericalError(f"subsystem {name}: its FMU does not restore its state (fmi2SetFMUstate off by "
                              f"{difference:.3g}, relative, at the set-up probe), so the iterations cannot "
                              f"converge: {text}")
    for sub in scene.subsystems:
        difference = repeat_difference(sub)
        if difference is not None and difference > BROKEN_RESTORE:
            return NumericalError(f"subsystem {sub.name}: its FMU does not restore its state (the same step made "
                                  f"twice from its saved state gave outputs {difference:.3g} apart, relative), so "
                                  f"the iterations cannot converge: {text}")
    return error


def named_for_cause(scene, error):
    """The error of a failed step named for what caused it: a NaN an FMU gave, or a broken restore."""
    return named_for_restore(scene, named_for_nan(scene, error))
