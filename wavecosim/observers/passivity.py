"""Condition 2 and the port energy ledger of every step: r_i = dH_i - (energy into port i) <= 0
(eq. 27), the energy the interface supplied, and the total stored energy."""
import math

from ..waves import physical_port_energy, port_energy
from . import Observer


def grow_max_pos(current, x):
    """Running max(0, x) over the numbers seen (NaN ignored); NaN until a number arrives."""
    if x != x:
        return current
    x = x if x > 0.0 else 0.0
    return current if current >= x else x


class Passivity(Observer):
    """Per step: r_<subsystem> (Condition 2), interface_supply and H_total; running maxima for the summary."""

    def __init__(self, scene):
        self.scene, self.wave, self.dt = scene, scene.wave, scene.scenario.dt
        self.names = [s.name for s in scene.subsystems]
        self.columns = (*[f"r_{n}" for n in self.names], "interface_supply", "H_total")

    def start(self, first):
        self.H = list(first.H)
        self.H_initial = self.H_max = sum(first.H)
        self.H_final = self.H_initial
        self.max_r = [math.nan] * len(self.names)
        self.max_supply, self.drift = math.nan, 0.0

    def after_step(self, n, t, log, reading, row):
        if self.wave:
            parts = zip(self.scene.split(log.a_hat), self.scene.split(reading.B))
            supplied = [port_energy(a, b) for a, b in parts]
            supply = port_energy(log.a_hat, reading.B)
        else:
            supplied = [physical_port_energy(e, f, self.dt) for e, f in
                        zip(self.scene.split(reading.E), self.scene.split(reading.F))]
            supply = sum(supplied)
        k = len(self.names)
        for i, (h0, h1, s) in enumerate(zip(self.H, reading.H, supplied)):
            r = (h1 - h0) - s
            row[i] = r
            self.max_r[i] = grow_max_pos(self.max_r[i], r)
        total = sum(reading.H)
        row[k], row[k + 1] = supply, total
        self.max_supply = grow_max_pos(self.max_supply, supply)
        self.drift += supply
        self.H, self.H_final = list(reading.H), total
        self.H_max = max(self.H_max, total) if total == total else total

    def summary(self):
        worst = [r for r in self.max_r if r == r]
        return {
            "max_passivity_pos": max(worst) if worst else math.nan,
            "max_passivity_pos_by_subsystem": dict(zip(self.names, self.max_r)),
            "H_initial": self.H_initial, "H_final": self.H_final,
            "H_growth": self.H_max / self.H_initial if self.H_initial > 0 else math.nan,
            "max_interface_injection": self.max_supply,
            "energy_drift": self.drift,
        }
