"""Condition 2 and the port energy ledger of every step: r_i = dH_i - (energy into port i) <= 0
(eq. 27), the energy the interface supplied, and the total stored energy.

A subsystem whose FMU has no stored-energy output (H) gets no r_i: its columns are the energy
supplied through its port in the step and cumulated (port_energy_<name>, port_energy_cum_<name>),
and the summary lists what could not be computed (certificates_unavailable)."""
import math

from ...kernel import blocks, cvalues
from ...core.waves import physical_port_energy, port_energy
from . import Observer


def grow_max_pos(current, x):
    """Running max(0, x) over the numbers seen (NaN ignored); NaN until a number arrives."""
    if x != x:
        return current
    x = x if x > 0.0 else 0.0
    return current if current >= x else x


class Passivity(Observer):
    """Per step: r_<subsystem> (Condition 2) or the port ledger without H, interface_supply and
    H_total (when every H is known); running maxima for the summary. `unavailable` names further
    certificates the run could not compute (from the runner)."""

    def __init__(self, scene, unavailable=()):
        self.scene, self.wave, self.dt = scene, scene.wave, scene.scenario.dt
        self.names = [s.name for s in scene.subsystems]
        self.has_H = [s.port.energy is not None for s in scene.subsystems]
        self.complete = all(self.has_H)
        self.blocks = self.complete and blocks.library() is not None
        self.call = None                  # the C pass's arguments, from the first block's layout
        missing = [n for n, h in zip(self.names, self.has_H) if not h]
        self.unavailable = [*(f"r_{n}" for n in missing), *([] if any(self.has_H) else ["max_passivity_pos"]),
                            *([] if self.complete else ["H_total", "H_growth"]), *unavailable]
        self.columns = (*[f"r_{n}" for n, h in zip(self.names, self.has_H) if h],
                        *[c for n in missing for c in (f"port_energy_{n}", f"port_energy_cum_{n}")],
                        "interface_supply", *(["H_total"] if self.complete else []))

    def start(self, first):
        self.H = list(first.H)
        self.H_initial = self.H_max = sum(first.H)
        self.H_final = self.H_initial
        self.max_r = [math.nan] * len(self.names)
        self.ledger = [0.0] * len(self.names)
        self.max_supply, self.drift = math.nan, 0.0

    def _supplied(self, log, reading):
        """Energy into each subsystem's port over the step, and into all of them."""
        if self.wave:
            parts = zip(self.scene.split(log.a_hat), self.scene.split(reading.B))
            return [port_energy(a, b) for a, b in parts], port_energy(log.a_hat, reading.B)
        supplied = [physical_port_energy(e, f, self.dt) for e, f in
                    zip(self.scene.split(reading.E), self.scene.split(reading.F))]
        return supplied, sum(supplied)

    def after_step(self, n, t, log, reading, row):
        supplied, supply = self._supplied(log, reading)
        k = 0
        for i, (h0, h1, s) in enumerate(zip(self.H, reading.H, supplied)):
            if self.has_H[i]:
                r = (h1 - h0) - s
                row[k] = r
                self.max_r[i] = grow_max_pos(self.max_r[i], r)
                k += 1
        for i, s in enumerate(supplied):
            if not self.has_H[i]:
                self.ledger[i] += s
                row[k], row[k + 1] = s, self.ledger[i]
                k += 2
        row[k] = supply
        self.max_supply = grow_max_pos(self.max_supply, supply)
        self.drift += supply
        total = sum(reading.H)
        if self.complete:
            row[k + 1] = total
        self.H, self.H_final = list(reading.H), total
        self.H_max = max(self.H_max, total) if total == total else total

    def _block_call(self, logs, readings):
        """The C pass's fixed arguments (kernel/c/blocks.c): the kernel log's rows it reads (the
        channels' a_hat, b, e, f, the subsystems' H), the ports' first channels, the running figures."""
        at, k, ints = logs.observed_at, len(self.names), blocks.ints
        rows = {key: ints([at + r for r in readings.rows(key)]) for key in ("B", "E", "F", "H")}
        prev, fig = cvalues.doubles(k), cvalues.doubles(k + 4)
        call = blocks.PassBlock(k=k, wave=int(self.wave), dt=self.dt, a=ints(logs.a_rows), b=rows["B"], e=rows["E"],
                                f=rows["F"], h=rows["H"], prev=prev, fig=fig,
                                port=ints([*self.scene.offsets, self.scene.n_channels]))
        return call, cvalues.ref(call), prev, fig

    def prepare_block(self, logs, readings):
        self.call = self._block_call(logs, readings)

    def after_block(self, n0, logs, readings, rows):
        """Every step's columns and the running figures in one C pass over the block's log, in
        after_step's operation order (kernel/c/blocks.c)."""
        k = len(self.names)
        if self.call is None:
            self.call = self._block_call(logs, readings)
        call, ref, prev, fig = self.call
        prev[:], fig[:] = self.H, [*self.max_r, self.max_supply, self.drift, self.H_max, self.H_final]
        call.count = len(logs)
        (call.log, call.ld), (call.out, call.ldo) = blocks.rows(logs.columns), blocks.columns(rows)
        blocks.library().passivity_block(ref)
        self.H, self.max_r = prev[:], fig[:k]
        self.max_supply, self.drift, self.H_max, self.H_final = fig[k:]

    def summary(self):
        worst = [r for r, h in zip(self.max_r, self.has_H) if h and r == r]
        out = {"max_passivity_pos": max(worst) if worst else math.nan} if any(self.has_H) else {}
        out["max_passivity_pos_by_subsystem"] = {n: r for n, r, h in zip(self.names, self.max_r, self.has_H) if h}
        if self.complete:
            out.update({"H_initial": self.H_initial, "H_final": self.H_final,
                        "H_growth": self.H_max / self.H_initial if self.H_initial > 0 else math.nan})
        else:
            out["port_energy_by_subsystem"] = {n: e for n, e, h in zip(self.names, self.ledger, self.has_H) if not h}
        out.update({"max_interface_injection": self.max_supply, "energy_drift": self.drift})
        if self.unavailable:
            out["certificates_unavailable"] = list(self.unavailable)
        return out
