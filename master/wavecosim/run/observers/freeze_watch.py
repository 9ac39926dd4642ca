"""The freeze watch: a subsystem whose outputs stay bit for bit the same over FROZEN_STEPS
consecutive committed macro-steps in which its inputs change has stopped advancing (an FMU that
ignores its doSteps and says OK), and the run is `suspect`, never `finished` without a word.

Per subsystem with a port: its outputs are its stored energy H (where the port names one) and the
port's output of each channel (a physical port: the effort or flow the FMU gives; a wave port: its
effort and flow), its inputs the other side of a physical port (the values the master set), or
for a wave port the effort and flow of the channels coupled to its own (its incoming waves come
from them). It only
reads the values the runner reads after every step (the Reading, or a block's rows at once)."""
from operator import itemgetter

import numpy as np

from . import Observer

FROZEN_STEPS = 20    # steps with the inputs changing and the outputs the same that make a subsystem suspect


class FreezeWatch(Observer):
    """Counts, per subsystem, the committed steps whose outputs equal the previous step's while its
    inputs differ; a stretch reaching FROZEN_STEPS is reported (once per subsystem, through warn)."""
    blocks = True

    def __init__(self, scene, warn):
        self.warn, self.dt, self.t0 = warn, scene.scenario.dt, scene.scenario.start_time
        self.names, self.outs, self.ins = [], [], []
        n, channels = len(scene.subsystems), sum(s.m for s in scene.subsystems)
        at = 0
        for i, s in enumerate(scene.subsystems):
            e, f = list(range(n + at, n + at + s.m)), list(range(n + channels + at, n + channels + at + s.m))
            if s.port.physical:
                flow_in = s.port.input_is_flow
                out = [ej if fi else fj for ej, fj, fi in zip(e, f, flow_in)]
                inp = [fj if fi else ej for ej, fj, fi in zip(e, f, flow_in)]
            else:
                out = e + f
                inp = [k for j in _neighbours(scene, range(at, at + s.m)) for k in (n + j, n + channels + j)]
            self.names.append(s.name)
            self.outs.append(([i] if s.port.energy else []) + out)
            self.ins.append(inp)
            at += s.m
        self.getters = [(itemgetter(*out), itemgetter(*inp) if inp else (lambda values: ())) for out, inp in
                        zip(self.outs, self.ins)]           # a step's outputs and inputs as tuples, compared at once
        self.last = None
        self.count = [0] * n                 # steps in the current stretch with outputs same, inputs changed
        self.since = [None] * n              # the first step of the current stretch of equal outputs
        self.found = {}                      # {subsystem: {"from_step", "from_t", "steps"}}

    @staticmethod
    def _flat(reading):
        return [*reading.H, *reading.E, *reading.F]

    def start(self, first):
        self.last = self._flat(first)

    def after_step(self, n, t, log, reading, row):
        now = self._flat(reading)
        last, self.last = self.last, now
        for i, (out, inp) in enumerate(self.getters):
            same = out(now) == out(last)
            if same or self.since[i] is not None:
                self._count(i, n, same, same and inp(now) != inp(last))

    def after_block(self, n0, logs, readings, rows, at=None):
        values = np.vstack([readings.H.T, readings.E.T, readings.F.T])       # one row per value, one column per step
        if not values.shape[1]:
            return
        changed = np.empty(values.shape, dtype=bool)
        changed[:, 0] = values[:, 0] != np.asarray(self.last, dtype=float)
        np.not_equal(values[:, 1:], values[:, :-1], out=changed[:, 1:])
        self.last = values[:, -1].tolist()
        for i, (out, inp) in enumerate(zip(self.outs, self.ins)):
            same = ~changed[out].any(axis=0)
            if not same.any():
                self.count[i], self.since[i] = 0, None
                continue
            moved = changed[inp].any(axis=0) & same
            if self.count[i] + int(moved.sum()) >= FROZEN_STEPS:       # a stretch may reach the limit: step by step
                for j, (s, m) in enumerate(zip(same.tolist(), moved.tolist())):
                    self._count(i, n0 + j, s, m)
                continue
            breaks = np.flatnonzero(~same)
            if len(breaks):                                            # the stretch after the last change
                after = int(breaks[-1]) + 1
                self.count[i] = int(moved[after:].sum())
                self.since[i] = n0 + after if after < len(same) else None
            else:
                self.count[i] += int(moved.sum())
                self.since[i] = n0 if self.since[i] is None else self.since[i]

    def _count(self, i, n, same, moved):
        """Step n of subsystem i: outputs the same as before it (same), and its inputs changed (moved)."""
        if not same:
            self.count[i], self.since[i] = 0, None
            return
        if self.since[i] is None:
            self.since[i] = n
        self.count[i] += moved
        name = self.names[i]
        if self.count[i] >= FROZEN_STEPS:
            steps = n + 1 - self.since[i]
            if name not in self.found:
                self.warn(f"subsystem {name}: its outputs stayed the same over {FROZEN_STEPS} macro-steps while its "
                          f"inputs changed (from t = {self.t0 + self.since[i] * self.dt:.6g}): the FMU seems not to "
                          f"advance; the run is marked suspect (see quirks.no_set_fmu_state_prior)")
                self.found[name] = {"from_step": self.since[i], "from_t": self.t0 + self.since[i] * self.dt,
                                    "steps": steps}
            elif self.found[name]["from_step"] == self.since[i] or steps > self.found[name]["steps"]:
                self.found[name].update(from_step=self.since[i], from_t=self.t0 + self.since[i] * self.dt,
                                        steps=steps)

    def verdict(self):
        if not self.found:
            return None
        return "frozen: " + ", ".join(f"{name} (outputs unchanged for {f['steps']} steps from t = {f['from_t']:.6g})"
                                      for name, f in self.found.items())

    def summary(self):
        return {"freeze_watch": {"steps": FROZEN_STEPS, "suspect": dict(self.found)}}


def _neighbours(scene, own):
    """The channels a coupling ties to the channels `own` (a row of E e + F f = 0 holding both)."""
    own = list(own)
    rows = (scene.E[:, own] != 0).any(axis=1) | (scene.F[:, own] != 0).any(axis=1)
    tied = (scene.E[rows] != 0).any(axis=0) | (scene.F[rows] != 0).any(axis=0)
    return [j for j in np.flatnonzero(tied).tolist() if j not in own]
