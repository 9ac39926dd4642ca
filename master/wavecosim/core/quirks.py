"""Quirks of real FMUs, found at set-up by a few doSteps of fresh instances from the initial state,
reported in metadata.json (`quirks`) and in one warning line each. Each FMU file is probed once, at
its first instance (what the probes find belongs to the binary), with two extra instances of it in
the same loaded binary; the subsystem's own instance is never stepped by a probe. A subsystem's
`quirks:` keys override the probes.

- `no_set_fmu_state_prior`: the noSetFMUStatePriorToCurrentPoint a master that rolls back passes
  to doStep. False is the standard's choice, but some FMUs stop advancing with false (status OK,
  outputs constant after the first step, or back at the start point). STEPS consecutive steps with
  false and then with true are made from the same restored state: false is kept only where the two
  agree as exactly as a restore does (within NOISE times the restore's own difference, bit for bit
  after an exact restore); otherwise the doSteps get true, with a note. Either flag is by the book
  here, as x_i^n is only ever restored at t_n, the doSteps' own communication point. Masters that
  never roll back pass true to every FMU.
- `restore`: the steps with false are made again after fmi2SetFMUstate; the largest relative
  difference of the outputs (0: the FMU restores its state exactly).
- `reentrant`: the second instance makes a step between the first one's input and its step; when
  that changes the first one's outputs, the instances share data in the binary. Then every
  further instance of the file (the lockstep reference's too) gets its own copy of the binary,
  after a second probe with such a copy; when even a copy disturbs, a second instance is refused
  in one line.
- `responds`: whether the port's outputs move when its inputs do (over the steps): a port that
  does not cannot be coupled, and a master would return a frozen trajectory for it.
During the run, run/observers/freeze_watch.py watches for a subsystem that stops advancing anyway.
An FMU that refuses a probe's step (its error is kept in `probe_error`) is left as if unprobed.

A restore found exact is re-checked during a supervised run (`RestoreWatch`): an FMU whose restore
goes wrong later would otherwise make the iterating masters silently wrong.
"""
import math
from dataclasses import asdict, dataclass

from ..errors import ConfigError, FmuError
from ..kernel import cvalues

KEYS = ("no_set_fmu_state_prior", "reentrant", "probe")     # a subsystem's `quirks:` keys
PERTURB = 1e-3           # the probe's input step, relative to 1 + |u|
MAX_OUTPUTS = 64         # FMU outputs compared, at most (beside the port's)
NOISE = 10.0             # a difference counts when above this many times the restore's own
STEPS = 4                # consecutive doSteps each probe makes from the saved state
RECHECK_EVERY = 1024     # the restore is re-checked after steps 2, 4, 8, ..., then every this many steps


@dataclass
class FmuQuirks:
    """What the probes found for one FMU file (None: not probed)."""
    file: str
    flags_agree: bool = None               # both flags' steps agree within the restore's own difference
    frozen_without_flag: bool = None       # stops advancing with noSetFMUStatePriorToCurrentPoint = false
    flag_difference: float = None          # relative output difference of the two flags' steps
    restore_difference: float = None       # relative output difference after fmi2SetFMUstate
    reentrant: bool = None                 # a second instance in the same binary leaves the first alone
    reentrant_copies: bool = None          # a second instance in its own copy of the binary does
    interference: float = None             # relative output difference a second instance caused
    responds: bool = None                  # the port's outputs move when its inputs do
    probe_error: str = None                # why the probes stopped (an instance refused a step)

    @property
    def needs_flag(self):
        return self.flags_agree is False

    def own_copies(self):
        """Further instances get their own copy of the binary."""
        return self.reentrant is False and self.reentrant_copies is not False


def _relative(rows_a, rows_b):
    """Largest |a - b| over the largest |a|, |b| of two lists of output rows (0 when equal)."""
    a = [x for row in rows_a for x in row]
    b = [x for row in rows_b for x in row]
    if a == b:
        return 0.0
    scale = max(max(map(abs, a), default=0.0), max(map(abs, b), default=0.0))
    worst = max(abs(x - y) for x, y in zip(a, b))
    return worst / scale if scale > 0 and math.isfinite(worst) else math.inf


class _Calls:
    """Status-checked raw fmi2-form calls on one instance, with the probe's inputs and outputs."""

    def __init__(self, fmu, in_vr, out_vr):
        self.fmu, self.comp = fmu, cvalues.pointer(fmu.component)
        self.fn = {name: fmu.raw_function(name) for name in
                   ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate", "fmi2SetReal", "fmi2DoStep",
                    "fmi2GetReal")}
        self.in_vr, self.out_vr = in_vr, out_vr
        self.u = cvalues.doubles(len(in_vr))
        self.y = cvalues.doubles(len(out_vr))
        self.t = 0.0                       # where a fresh instance's next step starts (_interferes)

    def call(self, name, *args):
        self.fmu.check(name, self.fn[name](self.comp, *args))

    def run(self, u, t0, h, flags):
        """One row of outputs per doStep, the inputs u held, from t0 on."""
        rows = []
        for k, flag in enumerate(flags):
            self.set(u)
            self.call("fmi2DoStep", cvalues.double(t0 + k * h), cvalues.double(h), int(flag))
            self.call("fmi2GetReal", self.out_vr, cvalues.size(len(self.out_vr)), self.y)
            rows.append(list(self.y))
        return rows

    def set(self, u):
        for j, x in enumerate(u):
            self.u[j] = x
        if len(u):
            self.call("fmi2SetReal", self.in_vr, cvalues.size(len(u)), self.u)

    def inputs(self):
        if not len(self.in_vr):
            return []
        self.call("fmi2GetReal", self.in_vr, cvalues.size(len(self.in_vr)), self.u)
        return list(self.u)

    def save(self, handle):
        self.call("fmi2GetFMUstate", cvalues.ref(handle))

    def restore(self, handle):
        self.call("fmi2SetFMUstate", handle)

    def free(self, handle):
        self.call("fmi2FreeFMUstate", cvalues.ref(handle))


def _outputs(sub):
    """Value references the probe compares: the port's outputs, then the FMU's Real outputs."""
    fmu = sub.fmu
    names = [v.name for v in fmu.description.modelVariables
             if v.causality == "output" and v.type == fmu.real_type and not getattr(v, "dimensions", None)]
    port = list(sub.port_vrs()[1])
    rest = [vr for vr in fmu.real_vrs(names[:MAX_OUTPUTS]) if vr not in port]
    return cvalues.uints(port + rest), len(port)


def _twin(sub, own_copy=False):
    """A fresh instance of the subsystem's FMU for the probes (None when none can be opened)."""
    try:
        return sub.fmu.twin(f"{sub.name}~probe", own_copy)
    except FmuError:
        return None


def _interferes(a, b, hx, u1, u_other, t0, h, alone, noise):
    """Relative change of a's first-step outputs (from the state in hx) when b sets its input and
    steps in between; 0 when within the restore's noise."""
    a.restore(hx)
    a.set(u1)
    b.set(u_other)
    a.call("fmi2DoStep", cvalues.double(t0), cvalues.double(h), 0)
    b.call("fmi2DoStep", cvalues.double(b.t), cvalues.double(h), 1)
    b.t += h
    a.call("fmi2GetReal", a.out_vr, cvalues.size(len(a.out_vr)), a.y)
    diff = _relative([list(a.y)], [alone])
    return diff if diff > noise else 0.0


def probe(sub):
    """The quirks of sub's FMU, found with fresh instances of it: the subsystem's own instance is
    never stepped, so a probe that fails (the FMU refuses the perturbed input) leaves the run as it
    would be without it."""
    found = FmuQuirks(sub.fmu.path.name)
    if not sub.fmu.can_save_state or sub.fmu.once_per_process:
        return found
    own, kept = _Calls(sub.fmu, *sub.port_vrs()), cvalues.pointer()
    own.save(kept)                       # a non-reentrant FMU's probes move it: put back below
    twins = []
    try:
        _probe_twins(found, sub, twins)
    except FmuError as exc:
        found.probe_error = str(exc)
    finally:
        for twin in reversed(twins):
            twin.close()
        if found.reentrant is False:
            own.restore(kept)
        own.free(kept)
    return found


def _open(sub, twins, own_copy=False):
    """A fresh instance and its calls (kept in twins, to be closed); FmuError when none opens."""
    fmu = _twin(sub, own_copy)
    if fmu is None:
        raise FmuError(f"subsystem {sub.name}: a second instance of {sub.fmu.path.name} could not be opened")
    twins.append(fmu)
    out_vr, m_out = _outputs(sub)
    return _Calls(fmu, sub.port_vrs()[0], out_vr), m_out


def _probe_twins(found, sub, twins):
    """B steps with false from a saved state (restore and input response); C steps between B's
    input and B's step (reentrancy), and if it disturbs, D from its own copy of the binary does the
    same; last, B steps with true from the same saved state (the flag: true promises that no earlier
    state is set again)."""
    b, m_out = _open(sub, twins)
    t0, h = sub.fmu.start_time, sub.dt / sub.substeps      # the FMU's own doStep
    u0 = b.inputs()
    du = [PERTURB * (1.0 + abs(x)) for x in u0]
    u1, u_other = [x + d for x, d in zip(u0, du)], [x - d for x, d in zip(u0, du)]
    hx, without = cvalues.pointer(), (False,) * STEPS
    b.save(hx)
    moved = b.run(u1, t0, h, without)
    b.restore(hx)
    rest = b.run(u0, t0, h, without)
    b.restore(hx)
    again = b.run(u1, t0, h, without)
    found.restore_difference = _relative(moved, again)
    found.responds = [r[:m_out] for r in moved] != [r[:m_out] for r in rest] if m_out else None
    noise = NOISE * found.restore_difference
    c, _ = _open(sub, twins)
    c.t = t0
    found.interference = _interferes(b, c, hx, u1, u_other, t0, h, moved[0], noise)
    found.reentrant = found.interference == 0.0
    if not found.reentrant:
        d, _ = _open(sub, twins, own_copy=True)
        d.t = t0
        found.reentrant_copies = _interferes(b, d, hx, u1, u_other, t0, h, moved[0], noise) == 0.0
    b.restore(hx)
    stepped = b.run(u1, t0, h, (True,) * STEPS)
    found.flag_difference = _relative(again, stepped)
    found.flags_agree = found.flag_difference <= noise
    found.frozen_without_flag = not found.flags_agree and _stalls(again) and not _stalls(stepped)
    b.free(hx)


def _stalls(rows):
    """The outputs are the same after every step from the second on (the FMU stopped advancing)."""
    return all(row == rows[1] for row in rows[2:])


@dataclass
class Decision:
    """What a subsystem runs with, and why (metadata.json's `quirks` entry)."""
    file: str
    no_set_fmu_state_prior: bool
    chosen_by: str                   # probe | quirks key | no rollback | default
    own_copy: bool
    found: dict


class QuirkTable:
    """The probes' findings per FMU file, shared by the scenes of one process's run (a run and its
    lockstep reference), so each file is probed once."""

    def __init__(self):
        self.files = {}                  # {FMU path: FmuQuirks}

    def own_copy(self, sub_cfg, path, where):
        """Whether this subsystem's instance gets its own copy of the binary; refuses an FMU found not
        to run twice in one process in one line."""
        key = (sub_cfg.quirks or {}).get("reentrant")
        if key is not None:
            return not key
        found = self.files.get(str(path))
        if found is None:
            return False
        if found.reentrant is False and found.reentrant_copies is False:
            raise ConfigError(f"{where}: {found.file} cannot run twice in one process: a second instance, even "
                              f"from its own copy of the binary, changes the first one's outputs (by "
                              f"{found.interference:.3g}, relative); only one instance of it can run")
        return found.own_copies()

    def settle(self, sub, sub_cfg, path, rollback, where, own_copy, notes):
        """Probe sub's FMU file at its first instance (unless `quirks.probe` is false; what is found
        goes to `notes`), then set the doStep flag the subsystem runs with; returns its Decision."""
        keys = sub_cfg.quirks or {}
        found = self.files.get(str(path))
        if found is None and keys.get("probe", True):
            found = self.files[str(path)] = probe(sub)
            notes.extend(self._notes(found, where, rollback, keys))
        flag, how = False, "default"
        if not rollback:
            flag, how = True, "no rollback"
        elif "no_set_fmu_state_prior" in keys:
            flag, how = bool(keys["no_set_fmu_state_prior"]), "quirks key"
        elif found is not None and found.flags_agree is not None:
            flag, how = found.needs_flag, "probe"
        sub.no_prior = int(flag)
        found = {k: v for k, v in asdict(found).items() if k != "file"} if found is not None else {}
        return Decision(path.name, flag, how, own_copy, found)

    @staticmethod
    def _notes(found, where, rollback, keys):
        """One warning line per quirk found."""
        notes, name = [], found.file
        if found.flags_agree is False:
            given = ("its doSteps get true (quirks.no_set_fmu_state_prior overrides)" if rollback
                     and "no_set_fmu_state_prior" not in keys else "it gets true" if not rollback else
                     f"quirks.no_set_fmu_state_prior is {keys['no_set_fmu_state_prior']}")
            how = ("does not advance when doStep gets noSetFMUStatePriorToCurrentPoint = false (outputs "
                   "constant after the first step, status OK) and moves with true" if found.frozen_without_flag
                   else f"gives other outputs over {STEPS} steps when doStep gets noSetFMUStatePriorToCurrentPoint"
                        f" = false than with true (relative difference {found.flag_difference:.3g}, beyond its "
                        f"restore's {found.restore_difference:.3g})")
            notes.append(f"{where}: {name} {how}: {given}")
        if rollback and found.restore_difference:
            notes.append(f"{where}: {name} restores its state only to {found.restore_difference:.3g} "
                              f"(relative, two steps after fmi2SetFMUstate): iterating masters see that noise")
        if found.reentrant is False:
            more = ("further instances get their own copy of the binary" if found.reentrant_copies
                    else "a second instance in the same process is refused")
            notes.append(f"{where}: {name} is not reentrant: a second instance changes the first one's "
                              f"outputs (by {found.interference:.3g}, relative); {more}")
        if found.responds is False:
            notes.append(f"{where}: the port outputs of {name} do not move when its inputs do (two steps "
                              f"from the initial state): the coupling cannot move it, so the run would be frozen")
        return notes


class RestoreWatch:
    """The restore re-checked during a run, on each subsystem whose probe found it exact (a master that
    rolls back relies on it): its state saved, its outputs read, the state set back and the outputs
    read again, which must be the same. The checks come after fixed steps (`next`: 2, 4, 8, ...,
    RECHECK_EVERY, then every RECHECK_EVERY steps), the same in every run and route, so a restore
    that moves an FMU a little moves it alike everywhere; five FMU calls per RECHECK_EVERY steps."""

    def __init__(self, scene, rollback):
        exact = [s for s in scene.subsystems if rollback and s.fmu is not None
                 and (scene.decisions.get(s.name) and scene.decisions[s.name].found.get("restore_difference") == 0.0)]
        self.checks = [(s, _Calls(s.fmu, cvalues.uints([]), _outputs(s)[0])) for s in exact]
        self.next = 2 if self.checks else math.inf
        self.handle = cvalues.pointer()

    def after(self, n):
        """After macro-step n - 1 (n steps made): the check due there; FmuError when a restore drifted."""
        if n != self.next:
            return
        for sub, calls in self.checks:
            self._check(sub, calls, n)
        self.next = 2 * n if n < RECHECK_EVERY else n + RECHECK_EVERY

    def _check(self, sub, calls, n):
        out = cvalues.size(len(calls.out_vr))
        calls.save(self.handle)
        calls.call("fmi2GetReal", calls.out_vr, out, calls.y)
        before = list(calls.y)
        calls.restore(self.handle)
        calls.call("fmi2GetReal", calls.out_vr, out, calls.y)
        after = list(calls.y)
        calls.free(self.handle)
        if before != after:
            raise FmuError(f"subsystem {sub.name}: its restore no longer reproduces its state: fmi2SetFMUstate "
                           f"after step {n} changed its outputs by {_relative([before], [after]):.3g} (relative); "
                           f"a master that rolls back would give wrong results", subsystem=sub.name, step=n)
