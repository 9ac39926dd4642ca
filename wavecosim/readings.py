"""What the runner reads from the FMUs after each macro-step, in one raw getReal per subsystem:
stored energy H_i, stage effort and flow, the outgoing waves (wave masters) and the recorded outputs.
A physical port (wavecosim/ports.py) gives its oriented e, f and the wave b; H_i is NaN where the FMU
has no stored-energy output."""
import math
from dataclasses import dataclass


@dataclass
class Reading:
    """The FMUs' values at x^{n+1}: per subsystem H_i, and stacked over the channels e, f and b."""
    H: list
    E: list
    F: list
    B: list
    outputs: list


class Sampler:
    """Reads a Reading from every subsystem of a scene; buffers and value references are fixed at
    set-up, so a step costs one C call per subsystem."""

    def __init__(self, scene, outputs):
        self.parts = []
        for s in scene.subsystems:
            cols = [var for ref in outputs.values() for name, var in [ref.split(".", 1)] if name == s.name]
            if s.port.physical:
                self.parts.append(self._physical_part(s, cols))
                continue
            names = [s.port.energy, *s.port.effort, *s.port.flow, *(s.port.wave_out if scene.wave else [])]
            read, buf = s.reader(names + cols)
            self.parts.append((read, s.m, len(names)))
        owner = [ref.split(".", 1)[0] for ref in outputs.values()]
        order = [(i, sum(1 for o in owner[:k] if o == s.name)) for k, o in enumerate(owner)
                 for i, s in enumerate(scene.subsystems) if s.name == o]
        self._order = order
        by_name = {s.name: s for s in scene.subsystems}
        self.units = {col: by_name[ref.split(".", 1)[0]].fmu.variable(ref.split(".", 1)[1]).unit or ""
                      for col, ref in outputs.items()}

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
        return Reading(H, E, F, B, [own[i][j] for i, j in self._order])
