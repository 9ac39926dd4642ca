"""What the runner reads from the FMUs after each macro-step, in one raw getReal per subsystem:
stored energy H_i, stage effort and flow, the outgoing waves (wave masters) and the recorded outputs.
A physical port (wavecosim/core/ports.py) gives its oriented e, f and the wave b; H_i is NaN where the FMU
has no stored-energy output."""
import math
from dataclasses import dataclass

import numpy as np

from ..fmi.values import BINARY, STRING, category, unit_of
from ..kernel.portview import ObservedPort


@dataclass
class Reading:
    """The FMUs' values at x^{n+1}: per subsystem H_i, and stacked over the channels e, f and b."""
    H: list
    E: list
    F: list
    B: list
    outputs: list


class BlockReading:
    """The Readings of many macro-steps as 2-D arrays, one row per step: H (steps x subsystems),
    E, F, B (steps x channels) and outputs (steps x output columns), each taken when first read
    from the observed values (Sampler.observed concatenated, one row per value, one column per step):
    a view where its values are evenly spaced (readings.as_index), else a copy."""
    KEYS = ("H", "E", "F", "B", "outputs")

    def __init__(self, observed, columns):
        self._observed, self._columns = observed, columns

    def __getattr__(self, key):
        if key not in BlockReading.KEYS:
            raise AttributeError(key)
        value = self._observed[self._columns[key]].T
        setattr(self, key, value)
        return value

    def rows(self, key):
        """Which rows of the observed values hold `key` (H, E, F, B or outputs), in order."""
        index = self._columns[key]
        return list(range(len(self._observed))[index]) if isinstance(index, slice) else [int(i) for i in index]


def row_sums(X):
    """linalg.total of each row of X, to the last bit: left to right from 0."""
    acc = 0.0 + X[:, 0]
    for j in range(1, X.shape[1]):
        acc = acc + X[:, j]
    return acc


def row_dots(A, B):
    """linalg.dot of each pair of rows of A and B, to the last bit: products summed left to right from 0
    (not numpy's a @ b, whose BLAS kernel, and so its order of sums, depends on the CPU)."""
    return row_sums(A * B)


def as_index(indices):
    """A list of indices as a slice when evenly spaced (a view, not a copy), else as an index array."""
    if not indices:
        return slice(0, 0)
    steps = {b - a for a, b in zip(indices, indices[1:])}
    if len(steps) > 1 or min(steps, default=1) < 1:
        return np.array(indices, dtype=np.intp)
    return slice(indices[0], indices[-1] + 1, steps.pop() if steps else 1)


class Sampler:
    """Reads a Reading from every subsystem of a scene; buffers and value references are fixed at
    set-up, so a step costs one C call per subsystem for its Real (Float64) values. Recorded
    outputs of other types (Integer, Boolean, String, ...) are read per subsystem and type in one
    call each and recorded as numbers (texts as the index of the text in `texts`)."""

    def __init__(self, scene, outputs):
        # observed: per subsystem the names read (H_i first; a physical port's ObservedPort), then per
        # subsystem stepped alone its outputs: what the kernel logs after each step of a block
        self.parts, self.observed = [], []
        everyone = scene.subsystems + scene.signal_only
        by_name = {s.name: s for s in everyone}
        refs = [ref.split(".", 1) for ref in outputs.values()]
        self.types = [by_name[name].fmu.kind(var) for name, var in refs]      # every column's FMI type
        raw = [by_name[name].fmu.real_type == kind for (name, _), kind in zip(refs, self.types)]
        self.typed = TypedReads(by_name, list(outputs), refs, raw, self.types)
        for s in scene.subsystems:
            cols = [var for (name, var), r in zip(refs, raw) if name == s.name and r]
            if s.port.physical:
                self.parts.append(self._physical_part(s, cols))
                self.observed.append(self._observed_port(s, cols))
                continue
            if s.port.physical:
                self.parts.append(self._physical_part(s, cols))
                self.observed.append(self._observed_port(s, cols))
                continue
            names = [s.port.energy, *s.port.effort, *s.port.flow, *(s.port.wave_out if scene.wave else [])]
            read, buf = s.reader(names + cols)
            self.parts.append((_macro_stage(s, read, names + cols) if s.multi_rate_wave else read, s.m, len(names)))
            self.observed.append(names + cols)
        alone = [[var for (name, var), r in zip(refs, raw) if name == s.name and r] for s in scene.signal_only]
        self.observed.extend(alone)
        self.alone = [s.reader(names)[0] for s, names in zip(scene.signal_only, alone)]
        index = {s.name: i for i, s in enumerate(everyone)}
        seen = {}                                  # per subsystem, its raw columns so far
        order = []
        for k, ((name, _), r) in enumerate(zip(refs, raw)):
            if r:
                order.append((index[name], seen.get(name, 0)))
                seen[name] = seen.get(name, 0) + 1
            else:
                order.append((-1, self.typed.slot[k]))
        self._order = order
        self.whole = not self.typed.groups            # outputs of other types are read in Python: no blocks
        self._columns = ({key: as_index(cols) for key, cols in self._block_columns(order).items()}
                         if self.whole else None)
        self.units = {col: unit_of(by_name[name].fmu.variable(var)) for col, (name, var) in zip(outputs, refs)}

    def _block_columns(self, order):
        """Where H, E, F, B and the outputs sit in the concatenated observed values of all subsystems
        (those stepped alone: outputs only, last)."""
        at, starts, cols = 0, [], {"H": [], "E": [], "F": [], "B": []}
        for (_, m, k), names in zip(self.parts, self.observed):
            starts.append(at)
            cols["H"].append(at)
            for key, first, last in (("E", 1, 1 + m), ("F", 1 + m, 1 + 2 * m), ("B", 1 + 2 * m, k)):
                cols[key].extend(range(at + first, at + last))
            at += len(names)
        heads = [k for _, _, k in self.parts]
        for names in self.observed[len(self.parts):]:
            starts.append(at)
            heads.append(0)
            at += len(names)
        cols["outputs"] = [starts[i] + heads[i] + j for i, j in order]
        return cols

    def rows(self, key):
        """Which of the observed values (all subsystems', concatenated) hold `key` (H, E, F, B or outputs);
        none when the outputs are not all read with them (no blocks)."""
        if self._columns is None:
            return []
        return BlockReading([None] * sum(map(len, self.observed)), self._columns).rows(key)

    def block(self, observed) -> BlockReading:
        """The BlockReading of observed values (the subsystems' `observed` names concatenated, one
        row per name, one column per step)."""
        return BlockReading(observed, self._columns)

    @staticmethod
    def _observed_port(s, cols):
        """What the kernel reads of a physical port for _physical_part's values (kernel/portview.py)."""
        names = [*([s.port.energy] if s.port.energy else []), *s.port.effort, *s.port.flow]
        return ObservedPort(names + cols, bool(s.port.energy), s.m, list(s.port.sign), bool(s.adapter), len(cols))

    @staticmethod
    def _physical_part(s, cols):
        """A reader for a physical port: [H or NaN, e..., f..., b... (adapter)] followed by the outputs."""
        names = [*([s.port.energy] if s.port.energy else []), *s.port.effort, *s.port.flow]
        raw, _ = s.reader(names + cols)
        m, h, sign = s.m, len(names) - 2 * s.m, s.port.sign

        def read():
            v = raw()[:]
            e, f = v[h:h + m], [si * x for si, x in zip(sign, v[h + m:h + 2 * m])]
            b = s.map.outgoing(e, f) if s.adapter else []
            return [v[0] if h else math.nan, *e, *f, *b, *v[h + 2 * m:]]
        return read, m, 1 + 2 * m + (m if s.adapter else 0)

    def read(self) -> Reading:
        H, E, F, B, own = [], [], [], [], []
        for read, m, k in self.parts:
            v = read()[:]
            H.append(v[0])
            E.extend(v[1:1 + m])
            F.extend(v[1 + m:1 + 2 * m])
            B.extend(v[1 + 2 * m:k])
            own.append(v[k:])
        own.extend(read()[:] for read in self.alone)         # signal-only subsystems: outputs only
        own.append(self.typed.read())                       # own[-1]: the outputs of other types
        return Reading(H, E, F, B, [own[i][j] for i, j in self._order])


def _macro_stage(s, read, names):
    """A multi-rate subsystem in the FMU's own wave mode: the values of its efforts, flows and outgoing
    waves among `names` are the macro-step's (the substeps' means, Subsystem._substeps), not the last
    substep's the FMU holds."""
    stage = [*s.port.effort, *s.port.flow, *s.port.wave_out]
    at = [(j, stage.index(name)) for j, name in enumerate(names) if name in stage]

    def macro():
        v = read()[:]
        made = s.macro_stage
        if made is not None:
            for j, i in at:
                v[j] = made[i]
        return v
    return macro


class TypedReads:
    """The recorded outputs whose type the raw fmi2GetReal does not read: per subsystem and FMI type
    one call; numbers (Integer, Boolean as 0 and 1, Float32) as floats, a String (a Binary as hex)
    as the index of its text in `texts[column]`, the distinct texts in the order first met."""

    def __init__(self, by_name, columns, refs, raw, types):
        self.groups, self.slot, self.texts = {}, {}, {}
        self._encode = []
        for k, ((name, var), r, kind) in enumerate(zip(refs, raw, types)):
            if r:
                continue
            self.slot[k] = len(self._encode)
            fmu = by_name[name].fmu
            vrs, slots = self.groups.setdefault((fmu, kind), ([], []))
            vrs.append(fmu.vr(var))
            slots.append(self.slot[k])
            text = category(kind) in (STRING, BINARY)
            if text:
                self.texts[columns[k]] = []
            self._encode.append(TextCodes(self.texts[columns[k]]) if text else float)

    def read(self):
        values = [0.0] * len(self._encode)
        for (fmu, kind), (vrs, slots) in self.groups.items():
            for slot, v in zip(slots, fmu.get_values(kind, vrs)):
                values[slot] = self._encode[slot](v)
        return values


class TextCodes:
    """A text as its index in `texts` (a String output's recorded value; bytes as hex)."""

    def __init__(self, texts):
        self.texts, self.index = texts, {}

    def __call__(self, value):
        text = value.hex() if isinstance(value, bytes) else value
        code = self.index.get(text)
        if code is None:
            code = self.index[text] = len(self.texts)
            self.texts.append(text)
        return float(code)
