"""Condition 2 and the port energy ledger of every step: r_i = dH_i - (energy into port i) <= 0
(eq. 27), the energy the interface supplied, and the total stored energy."""
import math

import numpy as np

from ..readings import GroupSums, row_sums
from ..waves import physical_port_energy, port_energy
from . import Observer


def grow_max_pos(current, x):
    """Running max(0, x) over the numbers seen (NaN ignored); NaN until a number arrives."""
    if x != x:
        return current
    x = x if x > 0.0 else 0.0
    return current if current >= x else x


def running_sum(start, x):
    """start + x[0] + x[1] + ..., added in that order (cumsum is sequential, unlike np.sum)."""
    return float(np.cumsum(np.concatenate([[start], x]))[-1])


class Passivity(Observer):
    """Per step: r_<subsystem> (Condition 2), interface_supply and H_total; running maxima for the summary."""

    def __init__(self, scene):
        self.scene, self.wave, self.dt = scene, scene.wave, scene.scenario.dt
        self.blocks = scene.wave
        self.port_sums = GroupSums([*[slice(off, off + s.m) for s, off in zip(scene.subsystems, scene.offsets)],
                                    slice(0, scene.n_channels)])
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

    def after_block(self, n0, logs, readings, rows):
        H, k = readings.H, len(self.names)
        a2, b2 = logs.a_hat * logs.a_hat, readings.B * readings.B
        supplied = 0.5 * (self.port_sums(a2) - self.port_sums(b2))    # each port, then all of them
        dH = np.empty_like(H)
        dH[0], dH[1:] = H[0] - self.H, H[1:] - H[:-1]
        rows[:, :k], rows[:, k], rows[:, k + 1] = dH - supplied[:, :k], supplied[:, k], row_sums(H)
        worst = np.fmax.reduce(rows[:, :k + 1], axis=0).tolist()
        self.max_r = [grow_max_pos(m, x) for m, x in zip(self.max_r, worst)]
        self.max_supply = grow_max_pos(self.max_supply, worst[k])
        self.drift = running_sum(self.drift, rows[:, k])
        total = rows[:, k + 1]
        self.H, self.H_final = H[-1].tolist(), float(total[-1])
        self.H_max = max(self.H_max, float(total.max()))   # a block holds no NaN H (the kernel stops)

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
