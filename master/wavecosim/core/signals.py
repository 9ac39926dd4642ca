"""Signal connections and sources: causal values held over each macro-step (sample and hold).

At the start of macro-step n every signal's value is read (an FMU's variable at t_n, i.e. after the
commit of step n - 1 or after initialization; a source table at t_n), converted to its input's
type (a Real scaled: to = factor * from + offset, SSP's LinearTransformation) and set on its input
before the frozen states x_i^n are saved, so every query and the commit of step n see the same
held inputs (an FMI 2 state includes its inputs). All values are read before any is set, so the
order of the signals never matters.

Signals carry every FMI type (wavecosim/fmi/values.py): a Real input takes a Real, Integer or
Boolean value; an integer input an integer or Boolean (range-checked); a Boolean a Boolean; a
String a String. This module is the one place that holds the values and their types: per
subsystem and FMI type, the value references read and set in one call each.
"""
import bisect
import math

from ..errors import ConfigError, FmuError, NumericalError
from ..fmi.values import BOOLEAN, INTEGER, REAL, STRING, category


class SourceTable:
    """A CSV time table read as fmpy's Input reads one: per column its value at t, held (the value
    of the last row at or before t: after an event at t) or linear between rows (at an event time,
    the value after it); before the first time the first row, after the last time the last row."""

    def __init__(self, cfg):
        self.name, self.how = cfg.name, cfg.interpolation
        self.times = [float(t) for t in cfg.times]
        self.columns = cfg.columns

    def kind(self, column, target):
        """The category a column's values have for an input of category `target`: BOOLEAN for
        true/false, INTEGER (or BOOLEAN) for whole numbers (or 0 and 1) feeding such an input,
        else REAL."""
        values = self.columns[column]
        if isinstance(values[0], bool):
            return BOOLEAN
        if target == INTEGER and all(v == int(v) for v in values):
            return INTEGER
        if target == BOOLEAN and all(v in (0.0, 1.0) for v in values):
            return BOOLEAN
        return REAL

    def value(self, column, t, linear):
        """The column's value at t (`linear`: interpolated between rows, else held)."""
        times, values = self.times, self.columns[column]
        i0 = bisect.bisect_left(times, t)
        if len(times) < 2 or i0 == 0:
            return values[0]
        if i0 == len(times):
            return values[-1]
        if not linear:
            i = i0 - 1
            while i + 1 < len(times) and (times[i + 1] < t or math.isclose(t, times[i + 1])):
                i += 1
            return values[i]
        if math.isclose(t, times[i0]) and i0 < len(times) - 1 and math.isclose(times[i0], times[i0 + 1]):
            while i0 < len(times) - 1 and math.isclose(times[i0], times[i0 + 1]):
                i0 += 1
            return values[i0]
        t0, t1 = times[i0 - 1], times[i0]
        w0 = (t1 - t) / (t1 - t0)
        return w0 * values[i0 - 1] + (1 - w0) * values[i0]


def _carried(where, fmu, name, var):
    """The FMI type of a variable a signal reads or drives, refused in one line when it has none
    wavecosim carries."""
    if var not in fmu.variables:
        raise ConfigError(f"{where}: the FMU {fmu.path.name} of {name} has no variable {var!r}")
    try:
        fmi_type = fmu.kind(var)
    except FmuError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    if category(fmi_type) not in (REAL, INTEGER, BOOLEAN, STRING):
        raise ConfigError(f"{where}: {name}.{var} is a {fmi_type} variable; signals carry Real, Integer, "
                          f"Enumeration, Boolean and String values")
    return fmi_type


def _target(where, fmu, name, var, port_vars=()):
    """The FMI type of the input a signal drives."""
    fmi_type = _carried(where, fmu, name, var)
    if fmu.variables[var].causality != "input":
        raise ConfigError(f"{where}: {name}.{var} is not an input of {fmu.path.name} (causality "
                          f"{fmu.variables[var].causality})")
    if var in port_vars:
        raise ConfigError(f"{where}: {name}.{var} is a port variable of {name}, so a signal cannot drive it")
    return fmi_type


def _converter(where, sig, kind, fmi_type):
    """The function that turns a value of category `kind` into the value the input of `fmi_type`
    takes: a Real scaled by the signal's factor and offset, other types as they are."""
    target = category(fmi_type)
    if target == REAL and kind in (REAL, INTEGER, BOOLEAN):
        factor, offset = sig.factor, sig.offset
        return lambda v: factor * float(v) + offset
    if (sig.factor, sig.offset) != (1.0, 0.0):
        raise ConfigError(f"{where}: a factor or offset scales Real inputs only; {sig.target} is a {fmi_type} input")
    convert = {(INTEGER, INTEGER): int, (INTEGER, BOOLEAN): int, (BOOLEAN, BOOLEAN): bool, (STRING, STRING): str}
    if (target, kind) not in convert:
        raise ConfigError(f"{where}: {sig.source} gives {kind} values, which cannot drive {sig.target}, a "
                          f"{fmi_type} input")
    return convert[(target, kind)]


def _linear(table, fmi_type, target):
    """Whether a table drives an input by linear interpolation: a continuous Real input of a table
    asked to (every other input holds the table's values, as fmpy applies them)."""
    return table.how == "linear" and category(fmi_type) == REAL and target.variability == "continuous"


def _group(groups, sub, fmi_type, vr, k):
    """Value reference vr of signal k in the per-subsystem, per-type calls."""
    vrs, ks = groups.setdefault(sub, {}).setdefault(fmi_type, ([], []))
    vrs.append(vr)
    ks.append(k)


class Signals:
    """The scenario's signals over opened subsystems ({name: Subsystem}, port and signal-only)."""

    def __init__(self, scenario, subsystems):
        self.t0, self.dt = scenario.start_time, scenario.dt
        self.where, self.refs = scenario.source, [sig.source for sig in scenario.signals]
        tables = {s.name: SourceTable(s) for s in scenario.sources}
        count = len(scenario.signals)
        self.convert, self.bounds, self.types = [None] * count, [None] * count, [None] * count
        self.tables, self.reads, self.writes = [], {}, {}    # (k, table, column, linear); {sub: {type: (vrs, ks)}}
        for k, sig in enumerate(scenario.signals):
            where = f"{scenario.source}: signals[{k}]"
            name, var = sig.target.split(".", 1)
            sub = subsystems[name]
            fmi_type = _target(f"{where}.to", sub.fmu, name, var, sub.port.physical_in + sub.port.wave_in)
            kind = self._source(f"{where}.from", sig, subsystems, tables, k, sub.fmu.variables[var], fmi_type)
            self.convert[k] = _converter(where, sig, kind, fmi_type)
            if category(fmi_type) == INTEGER:
                self.bounds[k] = sub.fmu.integer_range(fmi_type)
            self.types[k] = fmi_type
            _group(self.writes, sub, fmi_type, sub.fmu.vr(var), k)
        self.targets = [sig.target for sig in scenario.signals]
        self.driven = sorted({s.name for s in self.writes})

    def _source(self, where, sig, subsystems, tables, k, target, fmi_type):
        """Book where signal k reads its value; returns the category of the values it reads."""
        name, var = sig.source.split(".", 1)
        if name in tables:
            self.tables.append((k, tables[name], var, _linear(tables[name], fmi_type, target)))
            return tables[name].kind(var, category(fmi_type))
        fmu = subsystems[name].fmu
        source_type = _carried(where, fmu, name, var)
        _group(self.reads, subsystems[name], source_type, fmu.vr(var), k)
        return category(source_type)

    def values(self, t):
        """Every signal's value at t, converted to its input's type (read before any is set)."""
        raw = [None] * len(self.convert)
        for sub, groups in self.reads.items():
            for fmi_type, (vrs, ks) in groups.items():
                for k, v in zip(ks, sub.fmu.get_values(fmi_type, vrs)):
                    raw[k] = v
        for k, table, column, linear in self.tables:
            raw[k] = table.value(column, t, linear)
        return [convert(v) for convert, v in zip(self.convert, raw)]

    def hold(self, n):
        """Read every signal at t_n, then set each on its input (held over macro-step n)."""
        t = self.t0 + n * self.dt
        values = self.values(t)
        self._check(values, n, t)
        for sub, groups in self.writes.items():
            for fmi_type, (vrs, ks) in groups.items():
                sub.fmu.set_values(fmi_type, vrs, [values[k] for k in ks])

    def _check(self, values, n, t):
        """A non-finite Real or an integer out of its input's range stops the run, naming the signal."""
        for k, v in enumerate(values):
            lo_hi = self.bounds[k]
            if (isinstance(v, float) and not math.isfinite(v)) or (lo_hi and not lo_hi[0] <= v <= lo_hi[1]):
                what = (f", outside the range {lo_hi[0]}..{lo_hi[1]} of the {self.types[k]} input {self.targets[k]}"
                        if lo_hi else "")
                raise NumericalError(f"{self.where}: signals[{k}]: {self.refs[k]} gave {v}{what} at step {n} "
                                     f"(t = {t:.6g})")


def table_inputs(scenario, name):
    """For the FMU of subsystem `name`: a function that sets, in initialization mode, the inputs
    that source tables drive to their values at the start time (fmpy's simulate applies its input
    so); None when no table drives an input of it."""
    tables = {s.name: SourceTable(s) for s in scenario.sources}
    mine = [(k, sig) for k, sig in enumerate(scenario.signals)
            if sig.target.split(".", 1)[0] == name and sig.source.split(".", 1)[0] in tables]
    if not mine:
        return None

    def set_inputs(fmu):
        groups = {}
        for k, sig in mine:
            where, var = f"{scenario.source}: signals[{k}]", sig.target.split(".", 1)[1]
            source, column = sig.source.split(".", 1)
            fmi_type = _target(f"{where}.to", fmu, name, var)
            table = tables[source]
            raw = table.value(column, scenario.start_time, _linear(table, fmi_type, fmu.variables[var]))
            value = _converter(where, sig, table.kind(column, category(fmi_type)), fmi_type)(raw)
            vrs, values = groups.setdefault(fmi_type, ([], []))
            vrs.append(fmu.vr(var))
            values.append(value)
        for fmi_type, (vrs, values) in groups.items():
            fmu.set_values(fmi_type, vrs, values)
    return set_inputs
