"""A scenario made concrete: FMU instances as Subsystems, stacked channels, the compiled coupling."""
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import interconnection as ic
from ..fmi.builtin import builtin_fmus
from ..kernel import linalg
from ..errors import ConfigError, CouplingError, FmuError, SimulationEnded
from ..fmi.fmu import Fmu
from ..fmi.fmi3 import BinaryError
from ..masters.adaptive import fmu_tolerance_cap
from .frozen_port_map import PortSpec, Subsystem
from .gamma import choose_relaxation, initial_gammas
from .kernel_scene import describe, unusable
from .ports import probe_signs
from .quirks import QuirkTable
from .recording import output_columns
from .signals import Signals, table_inputs


def resolve_fmu(sub, source="<scenario>") -> str:
    if sub.fmu_path is not None:
        if not sub.fmu_path.exists():
            raise ConfigError(f"{source}: subsystems.{sub.name}.fmu: FMU file not found: {sub.fmu_path}")
        return sub.fmu_path
    fmus = builtin_fmus()
    if sub.fmu not in fmus:
        raise ConfigError(f"{source}: subsystems.{sub.name}.fmu: no built-in FMU named {sub.fmu!r} "
                          f"(have: {', '.join(sorted(fmus))}; or give a path ending in .fmu)")
    return fmus[sub.fmu]


def _check_names(sub, fmu, p, keys):
    for key in keys:
        for name in p.get(key, []):
            if name not in fmu.variables:
                raise ConfigError(f"subsystems.{sub.name}.port.{key}: the FMU {fmu.path.name} has no variable "
                                  f"{name!r}")


def _physical_port_spec(sub, fmu, p) -> PortSpec:
    """A declared physical port: in/out variables must exist; the energy variable is optional."""
    _check_names(sub, fmu, p, ("physical_in", "physical_out", "wave_in", "wave_out"))
    for name in p["physical_in"]:
        if fmu.variable(name).causality != "input":
            raise ConfigError(f"subsystems.{sub.name}.port.physical_in: {name!r} is not an input of {fmu.path.name}")
    energy = p.get("energy", "H" if "H" in fmu.variables else None)
    if energy is not None and energy not in fmu.variables:
        raise ConfigError(f"subsystems.{sub.name}.port.energy: the FMU {fmu.path.name} has no variable {energy!r}")
    return PortSpec(wave_in=p.get("wave_in", []), wave_out=p.get("wave_out", []), effort=p["effort"],
                    flow=p["flow"], physical_in=p["physical_in"], input_is_flow=[k == "flow" for k in p["input"]],
                    energy=energy, physical_out=p["physical_out"], sign=list(p.get("sign", [])))


def _port_spec(sub, fmu) -> PortSpec:
    p = dict(sub.port)
    if "physical_out" in p:
        return _physical_port_spec(sub, fmu, p)
    m = len(p["wave_in"])
    if "physical_in" not in p:
        inputs = [v.name for v in fmu.description.modelVariables
                  if v.causality == "input" and v.name not in p["wave_in"]]
        p["physical_in"] = inputs if len(inputs) == m else []
    if "input" not in p and p["physical_in"]:
        kinds = []
        for phys, e, f in zip(p["physical_in"], p["effort"], p["flow"]):
            unit = fmu.variable(phys).unit
            kinds.append("flow" if unit and unit == fmu.variable(f).unit else
                         "effort" if unit and unit == fmu.variable(e).unit else None)
        p["input"] = kinds if None not in kinds else []
    _check_names(sub, fmu, p, ("wave_in", "wave_out", "effort", "flow", "physical_in"))
    if p["energy"] not in fmu.variables:
        raise ConfigError(f"subsystems.{sub.name}.port.energy: the FMU {fmu.path.name} has no variable "
                          f"{p['energy']!r}")
    return PortSpec(wave_in=p["wave_in"], wave_out=p["wave_out"], effort=p["effort"], flow=p["flow"],
                    physical_in=p.get("physical_in", []), input_is_flow=[k == "flow" for k in p.get("input", [])],
                    energy=p["energy"])


@dataclass
class Scene:
    """Instantiated subsystems of one run, the compiled interconnection between their channels, and
    the stacked maps every master uses: S(u) (eq. 13) and the commit advance(a) (eq. 21)."""
    scenario: object                     # the Scenario it was built from (plain data)
    subsystems: list
    offsets: list
    E: np.ndarray
    F: np.ndarray
    wave: bool
    gammas: dict                       # {subsystem: gamma}, the impedances P is compiled for
    notes: list = field(default_factory=list)        # warnings from set-up (orientation found by probing)
    port_signs: dict = field(default_factory=dict)   # {subsystem: {"sign": [...], "probed": bool}}
    signal_only: list = field(default_factory=list)  # Subsystems without a port (signals only)
    signals: Signals = None                          # the held signal inputs (None: the scenario has none)
    pool: dict = field(default_factory=dict)         # the extracted FMUs its instances share (fmi/fmu.py)
    quirks: QuirkTable = None                        # what the set-up probes found, per FMU file
    decisions: dict = field(default_factory=dict)    # {subsystem: quirks.Decision}: its doStep flag and why
    outputs: dict = field(default_factory=dict)      # the recorded columns {column: SUBSYSTEM.variable}
    ended: Exception = None                          # an FMU ended the simulation after the step just made

    @property
    def n_channels(self):
        return self.E.shape[0]

    @property
    def sizes(self):
        return [s.m for s in self.subsystems]

    def channel_gammas(self):
        """Impedance of every stacked channel: its subsystem's gamma."""
        return [self.gammas[s.name] for s in self.subsystems for _ in range(s.m)]

    def wave_map(self):
        """P and J_L compiled for the gammas in force."""
        return ic.compile_wave_map(self.E, self.F, self.channel_gammas(), where=f"{self.scenario.source}: couplings")

    def set_gammas(self, gammas):
        """New impedances ({subsystem: gamma}), only between macro-steps: each FMU's tunable gamma too."""
        for s in self.subsystems:
            if not s.adapter and "gamma" not in s.fmu.variables:
                raise ConfigError(f"{self.scenario.source}: subsystems.{s.name}.fmu: {s.fmu.path.name} has no "
                                  f"tunable parameter gamma, so gamma cannot be tuned")
            s.set_gamma(gammas[s.name])
        self.gammas = {s.name: float(gammas[s.name]) for s in self.subsystems}

    def begin_step(self, n, t):
        """Before anything of macro-step n (at t = t_n): hold the signal inputs, then one doStep of
        every signal-only subsystem (stepped once per macro-step with its own step size, never frozen;
        the tolerance mode puts it back from a snapshot when it rejects the step)."""
        if self.signals is not None:
            self.signals.hold(n, t)
        for s in self.signal_only:
            try:
                s.step_alone(n, t)
            except SimulationEnded as exc:          # the step done: the run ends after it (runner)
                if not exc.step_done:
                    raise
                self.ended = exc

    @property
    def steps_in_python(self):
        """Whether Python must act between the macro-steps (a held signal of another type than Real), so
        a master cannot make many of them in one kernel call; the kernel holds Real signals and steps
        the signal-only subsystems itself (kernel_signals)."""
        return (self.signals is not None or bool(self.signal_only)) and self.kernel_signals() is None

    def kernel_scene(self):
        """The scene as the C kernel's bindings take it (core/kernel_scene.py), made when a master opens
        its kernel route (a wave adapter moves to C then)."""
        return describe(self)

    def kernel_unusable(self):
        """Why the C kernel cannot run this scene, or None (core/kernel_scene.py)."""
        return unusable(self)

    def kernel_signals(self):
        """begin_step as plain data for the kernel's blocks (wavecosim/kernel/signals.py: the FMUs, port
        subsystems first, the signals, the subsystems stepped alone); None without signals and
        signal-only subsystems, or when Python must hold a signal (Signals.plan)."""
        if self.signals is None and not self.signal_only:
            return None
        everyone = self.subsystems + self.signal_only
        index = {id(s): j for j, s in enumerate(everyone)}
        plan = self.signals.plan(index) if self.signals is not None else \
            {"signals": [], "reads": [], "writes": [], "tables": None, "nonfinite": None}
        if plan is None:
            return None
        return {**plan, "subsystems": everyone, "alone": [index[id(s)] for s in self.signal_only],
                "t0": self.scenario.start_time, "dt": self.scenario.dt}

    def freeze(self, n, t):
        """Save every x_i^n (Algorithm 1, line 3)."""
        for s in self.subsystems:
            s.freeze(n, t)

    def S(self, u):
        """Stacked frozen port map S^n(u) = (S_A(u_A), S_B(u_B), ...) (eq. 13); the states are discarded."""
        b = []
        for s, u_i in zip(self.subsystems, self.split(u)):
            b.extend(s.query(u_i))
        return b

    def advance(self, a):
        """The one commit of a macro-step: every subsystem from x_i^n with a_i (eq. 21); returns b^{n+1}."""
        b = []
        for s, a_i in zip(self.subsystems, self.split(a)):
            b.extend(s.advance(a_i))
        return b

    def thaw(self):
        """Every instance back at x_i^n after queries made outside a master (certificates, probes)."""
        for s in self.subsystems:
            s.thaw()

    def restore_frozen(self):
        """Every instance back at x_i^n even after the commit (a step is redone)."""
        for s in self.subsystems:
            s.restore_frozen()

    def input_map(self):
        """G with inputs = G outputs for physical masters, from E e + F f = 0 split by causality."""
        n = self.n_channels
        if n == 0:
            return np.zeros((0, 0))
        is_flow_in = np.zeros(n, bool)
        for s, off in zip(self.subsystems, self.offsets):
            if len(s.port.input_is_flow) != s.m or len(s.port.physical_in) != s.m:
                raise ConfigError(f"{self.scenario.source}: subsystems.{s.name}.port: physical_in and input (flow/effort) are needed "
                                  f"for a physical-domain master")
            is_flow_in[off:off + s.m] = s.port.input_is_flow
        # columns of the unknown inputs (flows where flow is input, efforts otherwise) and known outputs
        Mx = np.where(is_flow_in, self.F, self.E)
        My = np.where(is_flow_in, self.E, self.F)
        X = linalg.solve_columns(Mx, My)
        if X is None:
            raise CouplingError(f"{self.scenario.source}: couplings: the port causalities do not fit the "
                                f"interconnection (inputs cannot be computed from outputs)")
        return -X

    def port_info(self):
        """Summary fields of physical ports: their signs and the wave adapters' doSteps per evaluation."""
        if not self.port_signs:
            return {}
        adapters = {s.name: s.map.info() for s in self.subsystems if s.adapter}
        return {"port_signs": self.port_signs, **({"wave_adapter": adapters} if adapters else {})}

    def signal_info(self):
        """Summary fields when signals drive inputs: which subsystems, and why their energy is not a
        violation."""
        if self.signals is None or not self.n_channels:      # no port: no energy to account for
            return {"signals": len(self.scenario.signals)} if self.signals is not None else {}
        driven = ", ".join(self.signals.driven)
        out = {"signals": len(self.scenario.signals), "signal_driven_subsystems": self.signals.driven,
               "signal_note": f"signals and sources drive inputs of {driven}: the energy they bring in is "
                              f"legitimate; the energy ledger watches only the interface, and a Condition 2 "
                              f"residual or H growth of {driven} includes that work, so it is not a passivity "
                              f"violation"}
        return out

    def map_noise(self):
        """Relative accuracy the frozen maps are solved to: the worst residual a wave adapter kept
        after a stall (an FMU smooth only to its own solver's tolerance); 0.0 for exact maps."""
        return max([s.map.worst_accepted for s in self.subsystems if s.adapter], default=0.0)

    def fmu_calls(self):
        """{subsystem: its FMU calls so far}, every FMU of the scene (those stepped alone too): its FMU's
        own counters, counted where each call is made (fmi/fmu.py in Python, kernel/c/fmicall.h in C)."""
        return {s.name: dict(s.calls) for s in self.subsystems + self.signal_only}

    def do_step_calls(self):
        """doStep calls made so far, over all subsystems (what a redo costs is the difference)."""
        return sum(c["doStep"] for c in self.fmu_calls().values())

    def split(self, x):
        """Per-subsystem slices of a stacked channel vector."""
        return [x[off:off + s.m] for s, off in zip(self.subsystems, self.offsets)]

    def choose_relaxation(self, b, P):
        """`master.relaxation: auto`, probed on this scene at x^0 around u^0 = P b (gamma.choose_relaxation)."""
        return choose_relaxation(self, b, P)

    def close(self):
        for s in self.subsystems + self.signal_only:
            s.close()


def _channels(ref, index, offsets, sizes, where):
    name, _, rest = ref.partition("[")
    k = index[name]
    if rest:
        j = int(rest[:-1])
        if j >= sizes[k]:
            raise ConfigError(f"{where}: {ref} names channel {j} but {name} has {sizes[k]} channel(s)")
        return [offsets[k] + j]
    return list(range(offsets[k], offsets[k] + sizes[k]))


def coupling_structure(scenario, sizes):
    """Global E, F over all channels from the scenario's list of couplings (empty without ports)."""
    if not scenario.subsystems:
        return np.zeros((0, 0)), np.zeros((0, 0)), []
    names = [s.name for s in scenario.subsystems]
    index = {n: i for i, n in enumerate(names)}
    offsets = list(np.cumsum([0] + list(sizes))[:-1])
    blocks = []
    for k, c in enumerate(scenario.couplings):
        where = f"{scenario.source}: couplings[{k}]"
        groups = [_channels(p, index, offsets, sizes, where) for p in c.ports]
        chans = [ch for g in groups for ch in g]
        made = ic.COUPLINGS[c.type](c, groups, where)
        if len(made) == 1:
            blocks.append((k, made[0][1], made[0][2], chans))
        else:
            blocks.extend((f"{k}{suffix}", E, F, [ch]) for (suffix, E, F), ch in zip(made, chans))
    label = [f"{n}[{j}]" for n, m in zip(names, sizes) for j in range(m)]     # global channel -> "A[0]"
    owner = {}
    for name, _, _, chans in blocks:
        k = str(name).split(".")[0]
        for ch in chans:
            if ch in owner:
                raise CouplingError(f"{scenario.source}: couplings[{k}].ports: channel {label[ch]} is already "
                                    f"connected by couplings[{owner[ch]}]")
            owner[ch] = k
    loose = [label[ch] for ch in range(len(label)) if ch not in owner]
    if loose:
        raise CouplingError(f"{scenario.source}: couplings: port channel(s) {', '.join(loose)} are not connected "
                            f"by any coupling")
    E, F = ic.assemble(blocks, int(sum(sizes)), where=f"{scenario.source}: couplings")
    ic.check_dirac(E, F, f"{scenario.source}: couplings")
    return E, F, offsets


def _open_fmu(scenario, sub, path, gamma, wave, pool=None):
    """One FMU instance with the subsystem's parameters, start values and port mode, left in
    initialization mode; a name the FMU lacks is reported at its key. Instances of one scene share
    the pool (one extraction per FMU file)."""
    reals = {**sub.parameters, **sub.start, "gamma": gamma}
    integers = {**sub.integers, "port_mode": 0 if wave else 1}
    try:
        return Fmu(path, sub.name, reals, integers, optional=("gamma", "port_mode"), pool=pool,
                   start_time=scenario.start_time, tolerance=sub.tolerance, initialize=table_inputs(scenario, sub.name),
                   hold=True, tolerance_at_most=fmu_tolerance_cap(scenario.master))
    except BinaryError as exc:
        raise FmuError(f"subsystem {exc}", subsystem=sub.name) from None
    except FmuError as exc:
        key = next((f"{k}.{exc.variable}" for k in ("parameters", "start", "integers")
                    if exc.variable in getattr(sub, k)), "fmu")
        raise ConfigError(f"{scenario.source}: subsystems.{sub.name}.{key}: {exc}") from None


def _check_fmu(scenario, sub, fmu, wave, needs_rollback):
    """Refuse an FMU this master cannot drive, in one line naming it."""
    where = f"{scenario.source}: subsystems.{sub.name}.fmu: {fmu.path.name}"
    if wave and "port_mode" not in fmu.variables and "physical_out" not in sub.port:
        raise ConfigError(f"{where} has no wave port (integer parameter port_mode); declare its physical port "
                          f"(port: physical_in, physical_out, input) or use a physical-domain master")
    if needs_rollback and not fmu.can_save_state:
        raise ConfigError(f"{where} cannot get and set its state, which every master here needs to freeze "
                          f"and roll back")


def _check_substeps(scenario, sub, fmu):
    """Refuse substeps on an FMU that keeps one communication step, unless that step is dt / substeps."""
    if sub.substeps == 1 or fmu.variable_steps:
        return
    h = scenario.dt / sub.substeps
    experiment = fmu.description.defaultExperiment
    fixed = float(experiment.stepSize) if experiment is not None and experiment.stepSize is not None else None
    if fixed is None or not math.isclose(fixed, h, rel_tol=1e-9):
        keeps = f"its step {fixed:.6g} s" if fixed is not None else "one step it does not declare"
        raise ConfigError(f"{scenario.source}: subsystems.{sub.name}.substeps: {sub.substeps} makes doSteps of "
                          f"{h:.6g} s, but {fmu.path.name} keeps {keeps} (canHandleVariableCommunicationStepSize="
                          f"\"false\"); give substeps = dt / its step, or leave it out")


def _orient(scenario, subsystem, notes):
    """A physical port's signs: as given, or probed from the initial state (noted once)."""
    port = subsystem.port
    if not port.physical:
        return None
    probed = not port.sign
    if probed and not subsystem.fmu.can_save_state:
        raise ConfigError(f"{scenario.source}: subsystems.{subsystem.name}.port.sign: missing, and "
                          f"{subsystem.fmu.path.name} cannot restore its state for the orientation probe; give the sign")
    if not probed:
        return {"sign": list(port.sign), "probed": probed}
    signs, slopes, steps = probe_signs(subsystem, f"{scenario.source}: subsystems.{subsystem.name}.port",
                                       scenario.start_time)
    subsystem.orient(signs)
    for j, (sign, slope, step) in enumerate(zip(signs, slopes, steps)):
        notes.append(f"{scenario.source}: subsystems.{subsystem.name}.port.sign not given: one doStep from the "
                     f"initial state gives d{port.physical_out[j]}/d{port.physical_in[j]} = {slope:.3g} (input step "
                     f"{step['step']:.3g}, confirmed by {step['check_slope']:.3g} at {step['check_step']:.3g}), so "
                     f"channel {j} takes sign {sign:+g} (power into the FMU = {sign:+g} e f)")
    return {"sign": list(port.sign), "probed": probed, "probe": steps}


def _subsystem(scenario, sub, path, gamma, wave, needs_rollback, pool=None):
    """One opened subsystem with its port (not yet oriented), or a signal-only one (no port)."""
    fmu = _open_fmu(scenario, sub, path, gamma, wave and not sub.signal_only, pool)
    try:
        _check_substeps(scenario, sub, fmu)
        if sub.signal_only:
            return Subsystem(sub.name, fmu, PortSpec([], [], [], [], energy=None), scenario.dt, wave=False,
                             substeps=sub.substeps)
        _check_fmu(scenario, sub, fmu, wave, needs_rollback)
        spec = _port_spec(sub, fmu)
        return Subsystem(sub.name, fmu, spec, scenario.dt, wave=wave, adapter=wave and spec.physical, gamma=gamma,
                         substeps=sub.substeps)
    except ConfigError as exc:
        fmu.close()
        text = str(exc)
        raise ConfigError(text if text.startswith(scenario.source) else f"{scenario.source}: {text}") from None


SETTLE_SWEEPS = 4      # sweeps of the initialization's propagation beyond one per FMU


def _signals(scenario, opened, notes):
    """The held signals over the opened subsystems: settled in initialization mode (Signals.settle,
    its note on a loop Newton solved goes to `notes`), then every FMU leaves it and the signals are
    set at t = 0 (so the orientation and gamma probes see them); None when the scenario has no signals."""
    signals = Signals(scenario, {s.name: s for s in opened}) if scenario.signals else None
    note = signals.settle(len(opened) + SETTLE_SWEEPS) if signals is not None else None
    notes.extend([note] if note else [])
    _end_initialization(opened)
    if signals is not None:
        signals.hold(0)
    return signals


def _end_initialization(opened):
    for s in opened:
        s.fmu.end_initialization()


def _open_all(scenario, subs, gammas, wave, needs_rollback, pool, quirks, opened, notes):
    """Open the subsystems `subs`, each FMU file's first instance probed for its quirks
    (core/quirks.py) before the next is opened, which then shares its binary or gets a copy of its
    own; the subsystems' quirk decisions."""
    decisions = {}
    for sub in subs:
        path, where = resolve_fmu(sub, scenario.source), f"{scenario.source}: subsystems.{sub.name}"
        own = quirks.own_copy(sub, path, f"{where}.fmu")
        opened.append(_subsystem(scenario, sub, path, gammas.get(sub.name, 1.0), wave, needs_rollback,
                                 None if own else pool))
        decisions[sub.name] = quirks.settle(opened[-1], sub, Path(path), needs_rollback, where, own, notes)
    return decisions


def build_scene(scenario, wave=True, needs_rollback=True, pool=None, quirks=None) -> Scene:
    """Instantiate every subsystem (wave or physical port mode) at its initial gamma and compile the
    coupling. A scene built alongside another (the lockstep reference) shares its `pool` of extracted
    FMUs (one binary per FMU file in the process) and its table of `quirks`."""
    gammas = initial_gammas(scenario)
    opened, notes, signs = [], [], {}
    pool, quirks = ({} if pool is None else pool), (QuirkTable() if quirks is None else quirks)
    try:
        decisions = _open_all(scenario, scenario.subsystems + scenario.signal_subsystems, gammas, wave, needs_rollback,
                              pool, quirks, opened, notes)
        signals = _signals(scenario, opened, notes)
        outputs, more = output_columns(scenario, opened)
        notes[:0] = list(dict.fromkeys(note for s in opened for note in s.fmu.notes))
        notes.extend(more)
        subsystems = opened[:len(scenario.subsystems)]
        for subsystem in subsystems:
            sign = _orient(scenario, subsystem, notes)
            if sign is not None:
                signs[subsystem.name] = sign
        E, F, offsets = coupling_structure(scenario, [s.m for s in subsystems])
        scene = Scene(scenario, subsystems, offsets, E, F, wave, gammas, notes, signs,
                      opened[len(subsystems):], signals, pool=pool, quirks=quirks, decisions=decisions,
                      outputs=outputs)
        if wave and scene.n_channels:
            scene.wave_map()
        return scene
    except BaseException:
        for s in opened:
            s.close()
        raise


def open_subsystems(scenario, names, wave=True):
    """The named subsystems alone, opened (their FMUs probed for quirks in this process) and oriented
    as build_scene opens them (a process that hosts part of a scene: its FMUs are loaded where they
    run). Signals are not held here."""
    gammas, opened, notes = initial_gammas(scenario), [], []
    try:
        _open_all(scenario, [s for s in scenario.subsystems if s.name in names], gammas, wave, True, {}, QuirkTable(),
                  opened, notes)
        _end_initialization(opened)
        for subsystem in opened:
            _orient(scenario, subsystem, notes)
        return opened
    except BaseException:
        for s in opened:
            s.close()
        raise
