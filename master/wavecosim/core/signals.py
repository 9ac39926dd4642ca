"""Signal connections and sources: causal values held over each macro-step (sample and hold).

At the start of macro-step n every signal's value is read (an FMU's variable at t_n, i.e. after the
commit of step n - 1 or after initialization; a source table at t_n), converted to its input's
type (a Real scaled: to = factor * from + offset, SSP's LinearTransformation) and set on its input
before the frozen states x_i^n are saved, so every query and the commit of step n see the same
held inputs (an FMI 2 state includes its inputs). All values are read before any is set, so the
order of the signals never matters.

In initialization mode the inputs that FMU outputs drive are settled first (Signals.settle): set
in dependency order, sweep after sweep, until a sweep changes no value to the last bit, as an FMPy
loop that repeats the propagation reports the start. An algebraic loop that does not settle is
solved by a damped Newton on its inputs (a warning says so), or refused in one line naming its
connections when Newton finds no solution.

Signals carry every FMI type (wavecosim/fmi/values.py): a Real input takes a Real, Integer or
Boolean value; an integer input an integer or Boolean (range-checked); a Boolean a Boolean; a
String a String. This module is the one place that holds the values and their types: per
subsystem and FMI type, the value references read and set in one call each.
"""
import bisect
import graphlib
import math
import struct

import numpy as np

from ..errors import ConfigError, FmuError, NumericalError
from ..fmi.values import BOOLEAN, INTEGER, REAL, STRING, category

NEWTON_ITERATIONS = 20      # of the damped Newton on an algebraic loop's inputs (Signals.settle)
NEWTON_TOLERANCE = 1e-12    # its largest residual, relative to 1 + the largest input
DIFFERENCE = 1e-7           # its Jacobian's difference step, relative to 1 + |input|


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
        self.sources = {}                                    # {k: (sub, FMI type, vr)} of signals an FMU drives
        self.inputs = {}                                     # {k: (sub, FMI type, vr)} of every signal's input
        self.looped = set()                                  # signals within an algebraic loop (settle)
        self.held = {}                                       # {k: the value settle set last}
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
            self.inputs[k] = (sub, fmi_type, sub.fmu.vr(var))
        self.targets = [sig.target for sig in scenario.signals]
        self.signals = list(scenario.signals)
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
        self.sources[k] = (subsystems[name], source_type, fmu.vr(var))
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

    def hold(self, n, t=None):
        """Read every signal at t_n (default t0 + n dt), then set each on its input (held over macro-step n)."""
        t = self.t0 + n * self.dt if t is None else t
        values = self.values(t)
        self._check(enumerate(values), n)
        for sub, groups in self.writes.items():
            for fmi_type, (vrs, ks) in groups.items():
                sub.fmu.set_values(fmi_type, vrs, [values[k] for k in ks])

    def settle(self, limit):
        """In initialization mode: set every input an FMU output drives from that output (converted),
        the FMUs in dependency order (Gauss-Seidel over the strongly connected groups), sweep after
        sweep until one changes no value bit for bit. An algebraic loop still moving after `limit`
        sweeps is solved by a damped Newton on its Real inputs, the rest swept again; returns a note
        then (else None). A loop Newton cannot solve is a NumericalError naming its connections."""
        order = self._dependency_order()
        moving = self._sweeps(order, limit)
        if not moving:
            return None
        loop = [k for k in moving if k in self.looped]
        if not loop or any(category(self.types[k]) != REAL for k in loop):
            raise NumericalError(self._unsettled(moving or loop, limit, ""))
        residual = self._newton(loop)
        if residual is None or self._sweeps(order, limit, fixed=set(loop)):
            raise NumericalError(self._unsettled(loop, limit, " and a damped Newton on its inputs finds no solution"))
        return (f"{self.where}: signals: the algebraic loop through {self._names(loop)} does not settle by "
                f"propagation in initialization mode; solved by a damped Newton on its inputs (residual "
                f"{residual:.3g})")

    def _sweeps(self, order, limit, fixed=()):
        """Sweeps over `order` (the signals in `fixed` left as they are) until one changes nothing;
        the signals the last of `limit` sweeps still changed ([] when settled)."""
        last, moving = None, []
        for _ in range(limit):
            held = []
            for sub, fmi_type, vrs, ks in order:
                mine = [(vr, k) for vr, k in zip(vrs, ks) if k not in fixed]
                values = [self.convert[k](self._read(k)) for _, k in mine]
                self._check(zip([k for _, k in mine], values), 0)
                if mine:
                    sub.fmu.set_values(fmi_type, [vr for vr, _ in mine], values)
                self.held.update((k, v) for (_, k), v in zip(mine, values))
                held.append([(k, _bits(v)) for (_, k), v in zip(mine, values)])
            if held == last:
                return []
            moving, last = [k for new, old in zip(held, last or held) for (k, a), (_, b) in zip(new, old)
                            if a != b], held
        return moving

    def _newton(self, loop):
        """Damped Newton on the loop's inputs u for G(u) = u, G the converted outputs read after
        setting u (Jacobian by differences); the FMUs are left at the solution. Its residual, or None."""
        u = np.array([self.held[k] for k in loop], dtype=float)
        r = self._loop_map(loop, u) - u
        for _ in range(NEWTON_ITERATIONS):
            worst = float(np.max(np.abs(r)))
            if worst <= NEWTON_TOLERANCE * (1.0 + float(np.max(np.abs(u)))):
                return worst
            jacobian = np.empty((len(loop), len(loop)))
            for j in range(len(loop)):
                step = u.copy()
                step[j] += DIFFERENCE * (1.0 + abs(u[j]))
                jacobian[:, j] = (self._loop_map(loop, step) - step - r) / (step[j] - u[j])
            try:
                du = np.linalg.solve(jacobian, -r)
            except np.linalg.LinAlgError:
                return None
            for halving in range(11):
                trial = u + du / 2.0 ** halving
                if np.all(np.isfinite(trial)):
                    r_trial = self._loop_map(loop, trial) - trial
                    if float(np.max(np.abs(r_trial))) < worst:
                        break
            else:
                return None
            u, r = trial, r_trial
        return None

    def _loop_map(self, loop, u):
        """Set the loop's inputs to u, then read its sources: G(u), converted."""
        for k, x in zip(loop, u):
            sub, fmi_type, vr = self.inputs[k]
            sub.fmu.set_values(fmi_type, [vr], [float(x)])
        return np.array([self.convert[k](self._read(k)) for k in loop], dtype=float)

    def _names(self, ks):
        return ", ".join(f"{self.refs[k]} -> {self.targets[k]}" for k in ks)

    def _unsettled(self, ks, limit, more):
        return (f"{self.where}: signals: the algebraic loop through {self._names(ks)} does not settle in "
                f"initialization mode ({limit} sweeps of setting inputs from outputs still change them){more}; "
                f"break it with a delay, or give start values at its solution")

    def _read(self, k):
        """The raw value of FMU-driven signal k, read now."""
        sub, fmi_type, vr = self.sources[k]
        return sub.fmu.get_values(fmi_type, [vr])[0]

    def _dependency_order(self):
        """[(target subsystem, FMI type, vrs, signals)] of the FMU-driven signals, the targets ordered
        so that a subsystem comes after those that drive it (a loop's members in the file's order).
        scipy is imported here, not with the module: most runs and every refusal never need it."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        subs = list(dict.fromkeys([self.sources[k][0] for k in self.sources] + list(self.writes)))
        index = {id(s): j for j, s in enumerate(subs)}
        edges = [(index[id(self.sources[k][0])], index[id(sub)]) for sub, groups in self.writes.items()
                 for _, ks in groups.values() for k in ks if k in self.sources]
        rows, cols = (list(x) for x in zip(*edges)) if edges else ([], [])
        graph = coo_matrix((np.ones(len(edges)), (rows, cols)), shape=(len(subs), len(subs)))
        _, group = connected_components(graph, directed=True, connection="strong")
        self.looped = {k for sub, groups in self.writes.items() for _, ks in groups.values() for k in ks
                       if k in self.sources and group[index[id(self.sources[k][0])]] == group[index[id(sub)]]}
        before = graphlib.TopologicalSorter({int(g): set() for g in group})
        for a, b in edges:
            if group[a] != group[b]:
                before.add(int(group[b]), int(group[a]))
        rank = {g: r for r, g in enumerate(before.static_order())}
        order = []
        for sub in sorted(self.writes, key=lambda s: (rank[int(group[index[id(s)]])], index[id(s)])):
            for fmi_type, (vrs, ks) in self.writes[sub].items():
                mine = [(vr, k) for vr, k in zip(vrs, ks) if k in self.sources]
                if mine:
                    order.append((sub, fmi_type, [vr for vr, _ in mine], [k for _, k in mine]))
        return order

    def _check(self, pairs, n):
        """A non-finite Real or an integer out of its input's range ((signal, value) pairs) stops the
        run at step n, naming the signal."""
        for k, v in pairs:
            lo_hi = self.bounds[k]
            if (isinstance(v, float) and not math.isfinite(v)) or (lo_hi and not lo_hi[0] <= v <= lo_hi[1]):
                raise NumericalError(self._message(k, v, n))

    def _message(self, k, v, n):
        """What a signal that gave a value its input cannot take says, at step n."""
        lo_hi, t = self.bounds[k], self.t0 + n * self.dt
        what = f", outside the range {lo_hi[0]}..{lo_hi[1]} of the {self.types[k]} input {self.targets[k]}" if lo_hi else ""
        return f"{self.where}: signals[{k}]: {self.refs[k]} gave {v}{what} at step {n} (t = {t:.6g})"

    def plan(self, index):
        """The signals as plain data for the kernel's blocks (wavecosim/kernel/signals.py), FMUs named by
        index[id(Subsystem)]: per signal (its table column or -1, its input's category, factor, offset,
        integer range), the get and set calls (FMU, category, value references, signals),
        tables(n0, count) (each table signal's value at t_n as a number, one row each) and the message
        of a value its input cannot take; None when a signal reads or drives a type the kernel does not
        carry (String, Float32, an FMI 3 integer or Boolean): Python holds those (hold)."""
        calls = []
        for part in (self.reads, self.writes):
            calls.append([(index[id(sub)], _carried_in_c(sub.fmu, fmi_type), list(vrs), list(ks))
                          for sub, by_type in part.items() for fmi_type, (vrs, ks) in by_type.items()])
        if any(kind is None for part in calls for _, kind, _, _ in part):
            return None
        column = {k: j for j, (k, _, _, _) in enumerate(self.tables)}
        signals = [(column.get(k, -1), category(self.types[k]), float(sig.factor), float(sig.offset),
                    *(self.bounds[k] or (-math.inf, math.inf))) for k, sig in enumerate(self.signals)]

        def tables(n0, count):
            return [[float(table.value(c, self.t0 + n * self.dt, linear)) for n in range(n0, n0 + count)]
                    for _, table, c, linear in self.tables]

        def message(k, value, n):
            return self._message(k, int(value) if category(self.types[k]) == INTEGER else value, n)
        return {"signals": signals, "reads": calls[0], "writes": calls[1], "tables": tables if self.tables else None,
                "nonfinite": message}


def _bits(value):
    """A value as compared by settle: a float by its bits (0.0 and -0.0 differ, a NaN equals itself)."""
    return struct.pack("<d", value) if isinstance(value, float) else value


def _carried_in_c(fmu, fmi_type):
    """The category the kernel's signals (kernel/c/signals.c) read or set fmi_type in, or None:
    Real (Float64) always, Integer, Enumeration and Boolean of an FMI 2 FMU."""
    if fmi_type == fmu.real_type:
        return REAL
    if fmu.fmi_version == "2.0" and fmi_type in ("Integer", "Enumeration", "Boolean"):
        return category(fmi_type)
    return None


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
