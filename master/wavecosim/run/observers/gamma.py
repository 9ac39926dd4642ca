"""The impedances in force at each step (columns gamma_<subsystem>) and, for `gamma: auto |
auto-retune | fast-unsafe`, the tuner that chose them (wavecosim/core/gamma.py)."""
from ...errors import FmuError
from ...fmi.values import unit_of
from ...core.gamma import GammaTuner
from .fne_watch import trace_impedances
from . import Observer


class GammaLog(Observer):
    """Records gamma per step (fixed gammas: nothing to do before a step)."""
    when = "wave masters (dr, and newton for the reference)"
    described = {"gamma_<subsystem>": ("γ of the subsystem's port over the step", "effort/flow of the port")}

    def __init__(self, scene, master, tuner: GammaTuner = None):
        self.scene, self.master, self.tuner = scene, master, tuner
        self.names = [s.name for s in scene.subsystems]
        self.columns = tuple(f"gamma_{n}" for n in self.names)
        self.needs_trace = bool(tuner and tuner.retune)
        self.blocks = not self.needs_trace
        self.gamma_min = {}

    def unit(self, column):
        """The port's effort unit over its flow unit (N/(m/s)), from its FMU's modelDescription, when
        every channel gives the same; else the generic description."""
        sub = next(s for s in self.scene.subsystems if f"gamma_{s.name}" == column)
        try:
            units = {(unit_of(sub.fmu.variable(e)), unit_of(sub.fmu.variable(f)))
                     for e, f in zip(sub.port.effort, sub.port.flow)}
        except FmuError:                  # a port variable the FMU does not list (read another way)
            units = set()
        if len(units) != 1 or "" in next(iter(units)):
            return super().unit(column)
        effort, flow = units.pop()
        return f"{effort}/({flow})" if set(flow) & set("/. *") else f"{effort}/{flow}"

    def after_step(self, n, t, log, reading, row):
        if self.needs_trace and self.master.trace:
            self.tuner.observe(trace_impedances(self.scene, self.master.trace, self.scene.gammas))
        for i, name in enumerate(self.names):
            g = self.scene.gammas[name]
            row[i] = g
            self.gamma_min[name] = min(self.gamma_min.get(name, g), g)

    def after_block(self, n0, logs, readings, rows, at=None):
        gammas = [self.scene.gammas[name] for name in self.names]
        rows[:] = gammas                                        # one row, broadcast down the block
        for name, g in zip(self.names, gammas):
            self.gamma_min[name] = min(self.gamma_min.get(name, g), g)

    def summary(self):
        if self.tuner:
            return self.tuner.summary(self.gamma_min)
        return {"gamma_mode": "fixed", "gamma_initial": dict(self.scene.gammas), "gamma_final": dict(self.scene.gammas)}


class TunedGammaLog(GammaLog):
    """Records gamma per step and lets the tuner re-tune between macro-steps (auto-retune only)."""

    def before_step(self, n, t):
        self.tuner.between_steps(self.master, n, t)              # gamma changes only between macro-steps
