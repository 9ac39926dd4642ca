"""What the runner reads from the FMUs after each macro-step, in one raw getReal per subsystem:
stored energy H_i, stage effort and flow, the outgoing waves (wave masters) and the recorded outputs."""
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
