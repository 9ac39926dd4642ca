"""Signal connections and sources: causal values held over each macro-step (sample and hold).

At the start of macro-step n every signal's value is read (an FMU's variable at t_n, i.e. after the
commit of step n - 1 or after initialization; a source table at t_n), scaled (to = factor * from +
offset, SSP's LinearTransformation) and set on its input before the frozen states x_i^n are saved,
so every query and the commit of step n see the same held inputs (an FMI 2 state includes its
inputs). All values are read before any is set, so the order of the signals never matters. Then
each signal-only subsystem (no port) makes its one doStep of the macro-step.
"""
import math

import numpy as np

from ..errors import ConfigError, NumericalError

TIME_TOL = 1e-9          # a table time within TIME_TOL * dt above t_n counts as reached


class SourceTable:
    """A CSV time table: per column its value at t, held (the last time <= t) or linear; before the
    first time the first row, after the last time the last row."""

    def __init__(self, cfg, dt):
        self.name, self.how, self.tol = cfg.name, cfg.interpolation, TIME_TOL * dt
        self.times = np.asarray(cfg.times, float)
        self.columns = {c: np.asarray(v, float) for c, v in cfg.columns.items()}

    def value(self, column, t):
        values = self.columns[column]
        if self.how == "linear":
            return float(np.interp(t, self.times, values))
        k = int(np.searchsorted(self.times, t + self.tol, side="right")) - 1
        return float(values[max(k, 0)])


def _variable(where, sub, var, target):
    """The FMU variable a signal reads or drives: Real, and an input when it is driven."""
    fmu = sub.fmu
    if var not in fmu.variables:
        raise ConfigError(f"{where}: the FMU {fmu.path.name} of {sub.name} has no variable {var!r}")
    v = fmu.variables[var]
    if v.type != "Real":
        raise ConfigError(f"{where}: {sub.name}.{var} is a {v.type} variable; signals carry Real values")
    if target and v.causality != "input":
        raise ConfigError(f"{where}: {sub.name}.{var} is not an input of {fmu.path.name} (causality "
                          f"{v.causality})")
    if target and var in sub.port.physical_in + sub.port.wave_in:
        raise ConfigError(f"{where}: {sub.name}.{var} is a port variable of {sub.name}, so a signal cannot drive it")
    return fmu.vr(var)


class Signals:
    """The scenario's signals over opened subsystems ({name: Subsystem}, port and signal-only)."""

    def __init__(self, scenario, subsystems):
        self.dt = scenario.dt
        self.where, self.refs = scenario.source, [sig.source for sig in scenario.signals]
        tables = {s.name: SourceTable(s, scenario.dt) for s in scenario.sources}
        self.reads, self.writes = [], {}               # reads: value(t) per signal; writes: {sub: (vrs, rows)}
        for k, sig in enumerate(scenario.signals):
            where = f"{scenario.source}: signals[{k}]"
            name, var = sig.source.split(".", 1)
            if name in tables:
                self.reads.append(self._from_table(tables[name], var, sig))
            else:
                self.reads.append(self._from_fmu(subsystems[name], _variable(f"{where}.from", subsystems[name],
                                                                              var, False), sig))
            name, var = sig.target.split(".", 1)
            vrs, rows = self.writes.setdefault(subsystems[name], ([], []))
            vrs.append(_variable(f"{where}.to", subsystems[name], var, True))
            rows.append(k)
        self.driven = sorted({s.name for s in self.writes})

    @staticmethod
    def _from_table(table, column, sig):
        return lambda t: sig.factor * table.value(column, t) + sig.offset

    @staticmethod
    def _from_fmu(sub, vr, sig):
        return lambda t: sig.factor * float(sub.fmu.get_real([vr])[0]) + sig.offset

    def hold(self, n):
        """Read every signal at t_n, then set each on its input (held over macro-step n)."""
        t = n * self.dt
        values = [read(t) for read in self.reads]
        if not all(map(math.isfinite, values)):
            k = next(k for k, v in enumerate(values) if not math.isfinite(v))
            raise NumericalError(f"{self.where}: signals[{k}]: {self.refs[k]} gave {values[k]} at step {n} "
                                 f"(t = {t:.6g})")
        for sub, (vrs, rows) in self.writes.items():
            sub.fmu.set_real(vrs, [values[k] for k in rows])
