"""Condition 2 and the port energy ledger of every step: r_i = dH_i - (energy into port i) <= 0
(eq. 27), the energy the interface supplied, and the total stored energy.

A subsystem whose FMU has no stored-energy output (H) gets no r_i: its columns are the energy
supplied through its port in the step and cumulated (port_energy_<name>, port_energy_cum_<name>),
and the summary lists what could not be computed (certificates_unavailable)."""
import math

from ...kernel import blocks, cvalues
from ...kernel.linalg import total
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
    when = "every run of a scene with ports (`r_`: FMUs giving H, `port_energy_`: those without)"
    described = {
        "r_<subsystem>": ("Condition 2: ΔHᵢ minus the energy into the subsystem's port in the step "
                          "(≤ 0 up to roundoff for a passive step; a source inside the FMU adds its work)", "J"),
        "port_energy_cum_<subsystem>": ("the energy into the port since the start (a subsystem without H)", "J"),
        "port_energy_<subsystem>": ("the energy into the subsystem's port in the step: ½(‖âᵢ‖² − ‖bᵢ‖²) or "
                                    "Δt eᵢ·fᵢ (a subsystem without H, in place of r_<subsystem>)", "J"),
        "interface_supply": ("the energy into all ports in the step (the sum over the subsystems)", "J"),
        "H_total": ("Σᵢ Hᵢ, the energy stored in every subsystem after the step (when every FMU gives H)", "J"),
    }

    def __init__(self, scene, unavailable=()):
        self.scene, self.wave, self.dt = scene, scene.wave, scene.scenario.dt
        self.names = [s.name for s in scene.subsystems]
        self.has_H = [s.port.energy is not None for s in scene.subsystems]
        self.complete = all(self.has_H)
        self.blocks = blocks.library() is not None
        self.call = None                  # the C pass (blocks.Pass), from the blocks' layout (prepare_block)
        k = len(self.names)               # the running figures, owned here and updated in place by the C pass:
        self.prev = cvalues.doubles(k)    # the H_i before the next step;
        self.fig = cvalues.doubles(k + 4)     # each max r_i, then max_supply, drift, H_max, H_final;
        self.ledger = cvalues.doubles(k)  # the energy into each port without H, cumulated
        missing = [n for n, h in zip(self.names, self.has_H) if not h]
        self.unavailable = [*(f"r_{n}" for n in missing), *([] if any(self.has_H) else ["max_passivity_pos"]),
                            *([] if self.complete else ["H_total", "H_growth"]), *unavailable]
        self.columns = (*[f"r_{n}" for n, h in zip(self.names, self.has_H) if h],
                        *[c for n in missing for c in (f"port_energy_{n}", f"port_energy_cum_{n}")],
                        "interface_supply", *(["H_total"] if self.complete else []))

    def start(self, first):
        k = len(self.names)
        self.prev[:] = list(first.H)
        self.H_initial = total(first.H)
        self.fig[:] = [math.nan] * k + [math.nan, 0.0, self.H_initial, self.H_initial]
        self.ledger[:] = [0.0] * k

    def _supplied(self, log, reading):
        """Energy into each subsystem's port over the step, and into all of them."""
        if self.wave:
            parts = zip(self.scene.split(log.a_hat), self.scene.split(reading.B))
            return [port_energy(a, b) for a, b in parts], port_energy(log.a_hat, reading.B)
        supplied = [physical_port_energy(e, f, s.dt) for s, e, f in
                    zip(self.scene.subsystems, self.scene.split(reading.E), self.scene.split(reading.F))]
        return supplied, total(supplied)

    def after_step(self, n, t, log, reading, row):
        supplied, supply = self._supplied(log, reading)
        fig, k = self.fig, 0
        for i, (h0, h1, s) in enumerate(zip(self.prev, reading.H, supplied)):
            if self.has_H[i]:
                r = (h1 - h0) - s
                row[k] = r
                fig[i] = grow_max_pos(fig[i], r)
                k += 1
        for i, s in enumerate(supplied):
            if not self.has_H[i]:
                self.ledger[i] += s
                row[k], row[k + 1] = s, self.ledger[i]
                k += 2
        row[k] = supply
        at = len(self.names)
        H_total, H_max = total(reading.H), fig[at + 2]
        fig[at], fig[at + 1] = grow_max_pos(fig[at], supply), fig[at + 1] + supply
        if self.complete:
            row[k + 1] = H_total
        self.prev[:] = list(reading.H)
        fig[at + 2], fig[at + 3] = (max(H_max, H_total) if H_total == H_total else H_total), H_total

    def _block_pass(self, logs, readings):
        """The C pass (kernel/c/blocks.c, passivity_steps) with its fixed arguments: the kernel log's rows
        it reads (the channels' a_hat, b, e, f, the subsystems' H), the ports' first channels, the
        running figures."""
        at, k, ints = logs.observed_at, len(self.names), blocks.ints
        rows = {key: ints([at + r for r in readings.rows(key)]) for key in ("B", "E", "F", "H")}
        args = blocks.PassBlock(k=k, wave=int(self.wave), dt=self.dt, a=ints(logs.a_rows), b=rows["B"], e=rows["E"],
                                f=rows["F"], h=rows["H"], prev=self.prev, fig=self.fig, has_h=ints(self.has_H),
                                ledger=self.ledger, port=ints([*self.scene.offsets, self.scene.n_channels]))
        return blocks.Pass("passivity_steps", args)

    def prepare_block(self, logs, readings):
        self.call = self._block_pass(logs, readings)

    def block_pass(self):
        """Every step's columns and the running figures in C over the block's log, in after_step's
        operation order (kernel/c/blocks.c, passivity_steps)."""
        return self.call

    def summary(self):
        k = len(self.names)
        max_r, (max_supply, drift, H_max, H_final) = self.fig[:k], self.fig[k:]
        worst = [r for r, h in zip(max_r, self.has_H) if h and r == r]
        out = {"max_passivity_pos": max(worst) if worst else math.nan} if any(self.has_H) else {}
        out["max_passivity_pos_by_subsystem"] = {n: r for n, r, h in zip(self.names, max_r, self.has_H) if h}
        if self.complete:
            out.update({"H_initial": self.H_initial, "H_final": H_final,
                        "H_growth": H_max / self.H_initial if self.H_initial > 0 else math.nan})
        else:
            out["port_energy_by_subsystem"] = {n: e for n, e, h in zip(self.names, self.ledger, self.has_H) if not h}
        out.update({"max_interface_injection": max_supply, "energy_drift": drift})
        if self.unavailable:
            out["certificates_unavailable"] = list(self.unavailable)
        return out
