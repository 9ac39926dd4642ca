"""The freeze watch: a subsystem whose outputs stay bit for bit the same over FROZEN_STEPS
consecutive committed macro-steps in which its inputs change has stopped advancing (an FMU that
ignores its doSteps and says OK), and the run is `suspect`, never `finished` without a word.

Per subsystem with a port: its outputs are its stored energy H (where the port names one) and the
port's output of each channel (a physical port: the effort or flow the FMU gives; a wave port: its
effort and flow), its inputs the other side of a physical port (the values the master set), or
for a wave port the effort and flow of the channels coupled to its own (its incoming waves come
from them). It only reads the values the runner reads after every step (the Reading, or a block's
rows in the kernel's log)."""
import itertools
from operator import itemgetter

import numpy as np

from ...kernel import blocks, cvalues
from . import Observer

FROZEN_STEPS = 20    # steps with the inputs changing and the outputs the same that make a subsystem suspect
STATE = ("last", "count", "since", "found_from", "found_steps", "found_at", "first_from", "found_count")   # carried on


class FreezeWatch(Observer):
    """Counts, per subsystem, the committed steps whose outputs equal the previous step's while its
    inputs differ; a stretch reaching FROZEN_STEPS is reported (once per subsystem, through warn).
    Blocks of steps go to the C pass (kernel/c/blocks.c, freeze_steps), which carries the same state
    on in C arrays: it is handed over where the run goes from steps made one by one to blocks and back."""
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
        self.last = [0.0] * (n + 2 * channels)      # H, E and F after the step before
        self.count = [0] * n                 # steps in the current stretch with outputs same, inputs changed
        self.since = [-1] * n                # the first step of the current stretch of equal outputs (-1: none)
        self.found_from = [-1] * n           # the longest stretch found (-1: none): its first step, its steps
        self.found_steps = [0] * n
        self.found_at = [0] * n              # the step where the first stretch found reached FROZEN_STEPS
        self.first_from = [0] * n            # and that stretch's first step
        self.found_count = [0]               # subsystems found
        self.warned = set()
        self.c = {name: (cvalues.doubles if name == "last" else cvalues.ints)(getattr(self, name)) for name in STATE}
        self.in_c = False                    # whether the C arrays hold the state (a block came last)
        self.call = None                     # the C pass (blocks.Pass), from the blocks' layout

    @staticmethod
    def _flat(reading):
        return [*reading.H, *reading.E, *reading.F]

    def start(self, first):
        """The values at t = 0, in the C arrays too: a run that goes in blocks hands nothing over."""
        self.last[:] = self._flat(first)
        self._hand_over(to_c=True)

    def after_step(self, n, t, log, reading, row):
        self._in_python()
        now, last = self._flat(reading), self.last
        for i, (out, inp) in enumerate(self.getters):
            same = out(now) == out(last)
            if same or self.since[i] >= 0:
                self._count(i, n, same, same and inp(now) != inp(last))
        self.last = now
        if self.found_count[0] != len(self.warned):
            self._warn_found()

    def prepare_block(self, logs, readings):
        """The C pass with its fixed arguments: the kernel log's rows of H, E and F, each subsystem's
        outputs and inputs among them, the watch's state."""
        at, ints = logs.observed_at, cvalues.ints
        rows = [at + r for key in ("H", "E", "F") for r in readings.rows(key)]
        ends = lambda lists: ints([0, *itertools.accumulate(map(len, lists))])      # noqa: E731
        self.call = blocks.Pass("freeze_steps", blocks.FreezeBlock(
            k=len(self.names), frozen_steps=FROZEN_STEPS, n_values=len(rows), rows=ints(rows), out_at=ends(self.outs),
            outs=ints(sum(self.outs, [])), in_at=ends(self.ins), ins=ints(sum(self.ins, [])), **self.c))

    def block_pass(self):
        """The watch over a block's steps in C, in after_step's order (kernel/c/blocks.c, freeze_steps)."""
        return self.call

    def before_passes(self):
        if not self.in_c:
            self._hand_over(to_c=True)

    def after_passes(self):
        if self.c["found_count"][0] != len(self.warned):
            self._in_python()
            self._warn_found()

    def _in_python(self):
        """The state back from the C arrays after a block."""
        if self.in_c:
            self._hand_over(to_c=False)

    def _hand_over(self, to_c):
        """The state from the Python lists into the C arrays (to_c), or back."""
        for name in STATE:
            values, array = getattr(self, name), self.c[name]
            if to_c:
                array[:len(values)] = values
            else:
                setattr(self, name, array[:len(values)])
        self.in_c = to_c

    def _warn_found(self):
        """Warn of each subsystem found since the last warning, in the order found."""
        for i in self._found():
            if self.names[i] not in self.warned:
                self.warned.add(self.names[i])
                self.warn(f"subsystem {self.names[i]}: its outputs stayed the same over {FROZEN_STEPS} macro-steps "
                          f"while its inputs changed (from t = {self.t0 + self.first_from[i] * self.dt:.6g}): the FMU "
                          f"seems not to advance; the run is marked suspect (see quirks.no_set_fmu_state_prior)")

    def _count(self, i, n, same, moved):
        """Step n of subsystem i: outputs the same as before it (same), and its inputs changed (moved)."""
        if not same:
            self.count[i], self.since[i] = 0, -1
            return
        if self.since[i] < 0:
            self.since[i] = n
        self.count[i] += moved
        if self.count[i] < FROZEN_STEPS:
            return
        since, steps = self.since[i], n + 1 - self.since[i]
        if self.found_from[i] < 0:
            self.found_at[i], self.first_from[i] = n, since
            self.found_count[0] += 1
        elif self.found_from[i] != since and steps <= self.found_steps[i]:
            return
        self.found_from[i], self.found_steps[i] = since, steps

    def _found(self):
        """The subsystems found, in the order found."""
        return sorted((i for i in range(len(self.names)) if self.found_from[i] >= 0), key=lambda i: self.found_at[i])

    @property
    def found(self):
        """{subsystem: {"from_step", "from_t", "steps"}}: the longest stretch of each subsystem found."""
        self._in_python()
        return {self.names[i]: {"from_step": self.found_from[i], "from_t": self.t0 + self.found_from[i] * self.dt,
                                "steps": self.found_steps[i]} for i in self._found()}

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
