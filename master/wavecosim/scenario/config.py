"""Scenario files: read YAML safely, check every key, and return a plain validated Scenario.

Every problem becomes a ConfigError whose one line names the file and the key path.
"""
import csv
import math
import os
import re
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path

import yaml

from ..errors import ConfigError, brief_text
from ..examples import DEFAULT, resolve
from ..fmi.unpack import regular_file
from ..core.gamma import MODES as GAMMA_MODES
from ..core.interconnection import COUPLINGS, TAKES_RATIO
from ..core.quirks import KEYS as QUIRK_KEYS
from ..masters import ALGORITHMS
from ..masters.adaptive import FMU_SHARE
from ..masters.dr_options import ANDERSON_MAX, OPTION_MODES, STARTS
from .experiment import from_fmus
from .overrides import apply_overrides

DEFAULT_CONFIG = DEFAULT
GROWTH_BOUND = 1e12
INT32 = (-2 ** 31, 2 ** 31 - 1)       # an FMI Integer
MAX_SUBSTEPS = 10 ** 6                 # doSteps per macro-step of one subsystem
COUPLING_TYPES = tuple(COUPLINGS)
SIGNALS_MASTER = "explicit"            # the master of a system without power bonds


def key(doc, unit="", type="", default=None, name=None):
    """The metadata of a dataclass field that is a key of the scenario file: its meaning, unit and
    type as a reader sees them, its default where the field's own does not say it, and its name in
    the file where that differs from the field's. docs/scenario.md is generated from these
    (scripts/docs_tables.py); the checker accepts exactly the keys declared so (`keys_of`)."""
    return {"doc": doc, "unit": unit, "type": type, "default": default, "key": name}


def file_keys(cls):
    """[(key in the file, field)] of a dataclass's fields that are keys of the scenario file, in order."""
    return [(f.metadata.get("key") or f.name, f) for f in fields(cls) if "doc" in f.metadata]


def keys_of(cls):
    """The keys of the scenario file a mapping of this dataclass accepts, in order."""
    return tuple(k for k, _ in file_keys(cls))


IMPEDANCE = "effort/flow of the port (N·s/m for force and velocity)"


@dataclass
class SubsystemConfig:
    name: str
    fmu: str = field(metadata=key("a built-in FMU by its model name (`DuffingSide`), or the path of any .fmu, "
                                  "relative to the scenario file", type="text", default="required"))
    parameters: dict = field(metadata=key(
        "values set before initialization, by variable name (`resistor.R`), each with the setter of the type "
        "the FMU declares for it", type="mapping NAME: number, true/false or text", default="none"))
    start: dict = field(metadata=key("start values, by variable name, set as `parameters` are",
                                     type="mapping NAME: number, true/false or text", default="none"))
    integers: dict = field(metadata=key("Integer parameters, by variable name (e.g. `newton_max_iter`)",
                                        type="mapping NAME: integer", default="none"))
    port: dict = field(metadata=key(
        "the power port: which variables carry the waves or the effort and flow of each channel (keys below)",
        type="mapping", default="none; the wave port of the built-in FMUs when a coupling names the subsystem"))
    fmu_path: Path = None
    gamma: float = field(default=None, metadata=key(
        "this subsystem's γ, in place of the scenario's", IMPEDANCE, "number > 0", "the scenario's `gamma`"))
    tolerance: float = field(default=None, metadata=key(
        "the relative tolerance given to the FMU's set-up (`fmi2SetupExperiment`, "
        "`fmi3EnterInitializationMode`); at most `master.fmu_tolerance`", "1", "number > 0",
        "the FMU's DefaultExperiment tolerance; none when it gives none"))
    substeps: int = field(default=1, metadata=key(
        "multi-rate: doSteps of dt / substeps the FMU makes per macro-step, its coupling inputs held over the "
        "macro-step (Masters and DR, multi-rate)", "1", "integer >= 1", "1"))
    quirks: dict = field(default=None, metadata=key(
        "overrides of the quirk probes made at set-up (docs/troubleshooting.md): `no_set_fmu_state_prior` (the "
        "noSetFMUStatePriorToCurrentPoint its doSteps get), `reentrant` (false: its own copy of the binary), "
        "`probe` (false: none for its FMU file)", type="mapping of true/false",
        default="none: the probes decide"))

    @property
    def signal_only(self):
        """No port: the subsystem only exchanges signals (stepped once per macro-step, never frozen)."""
        return self.port is None


@dataclass
class SourceConfig:
    """A time table (CSV with a header, first column `time`): the value at t_n per column."""
    name: str
    csv: str = field(metadata=key(
        "the CSV file, relative to the scenario file: a header whose first column is `time`, then one row per "
        "time; numbers or true/false; times never decrease (a time given twice is an event)", "s (time column)",
        "file", "required"))
    interpolation: str = field(metadata=key(
        "`hold`: the value of the last row at or before t_n; `linear`: interpolated (continuous Real inputs only)",
        type="hold | linear", default="`hold`"))
    times: tuple                       # never decreasing; a time given twice is an event
    columns: dict                      # {column: tuple of values (floats, or bools), one per time}


@dataclass
class SignalConfig:
    """A causal connection, held over each macro-step: to = factor * from + offset (SSP LinearTransformation)."""
    source: str = field(metadata=key("where the value comes from: an FMU's output, or a column of a source",
                                     type="SUBSYSTEM.variable or SOURCE.column", default="required", name="from"))
    target: str = field(metadata=key("the input it drives (each input at most once; not a port variable and not "
                                     "one with a start value)", type="SUBSYSTEM.variable", default="required",
                                     name="to"))
    factor: float = field(default=1.0, metadata=key("to = factor · from + offset (Real inputs only)", "1", "number"))
    offset: float = field(default=0.0, metadata=key("to = factor · from + offset (Real inputs only)",
                                                    "the input's unit", "number"))


@dataclass
class CouplingConfig:
    type: str = field(metadata=key(
        "the lossless coupling: `equal_effort_opposite_flow` (two ports), `zero_junction` and `one_junction` "
        "(any number), `transformer` and `gyrator` (two ports, `ratio`), `free_end` and `clamped_end` (one port), "
        "`dirac` (any, with `E` and `F`)", type="text", default="required"))
    ports: list = field(metadata=key(
        "the port channels it joins: a subsystem's name (every channel of its port) or NAME[k] (channel k)",
        type="list", default="required"))
    ratio: float = field(default=None, metadata=key(
        "transformer: e₁ = n e₂ and n f₁ = −f₂; gyrator: e₁ = r f₂ and e₂ = −r f₁ (non-zero)",
        "effort₁/effort₂ (transformer), effort/flow (gyrator)", "number", "required for a transformer or gyrator"))
    E: list = field(default=None, metadata=key(
        "dirac: the matrix E of E e + F f = 0 over the joined channels (E Fᵀ + F Eᵀ = 0: lossless)",
        type="matrix (list of rows)", default="required for dirac"))
    F: list = field(default=None, metadata=key("dirac: the matrix F of E e + F f = 0", type="matrix (list of rows)",
                                               default="required for dirac"))


@dataclass
class MasterConfig:
    algorithm: str = field(default="dr", metadata=key(
        "the master (Masters and DR); a system without couplings runs only on `explicit`", type="name",
        default="`dr` where there are couplings, else `explicit`"))
    K: int = field(default=50, metadata=key("the inner budget: iterations per macro-step (DR, the iterating "
                                            "classical masters)", "1", "integer >= 0"))
    eps: float = field(default=None, metadata=key(
        "the inner tolerance: an inner loop also stops when its residual falls below eps", "sqrt(J) (waves)",
        "number > 0 or null", "none (K iterations)"))
    deadline_us: float = field(default=None, metadata=key(
        "wall-clock budget per macro-step: the inner loop stops early enough to end the step by it", "µs",
        "number > 0 or null", "none"))
    fast: str = field(default="auto", metadata=key(
        "the C kernel route: `auto` where it can run, `true`, `false` (the Python reference)",
        type="auto | true | false"))
    threads: str = field(default="auto", metadata=key(
        "threads evaluating the subsystems side by side (DR and the Jacobi family on the kernel route): N puts "
        "them on up to min(N, CPUs, subsystems) threads; `auto` adds threads only where they pay",
        type="auto or an integer >= 1"))
    energy_guard: str = field(default=None, metadata=key(
        "what keeps the run from gaining energy through the interface: `ledger` (the interface energy ledger), "
        "`monolithic` (redo as the monolithic step), `off` (Algorithm 1 as in the paper); true/false mean "
        "monolithic/off", type="ledger | monolithic | off",
        default="`ledger` for dr; `off` for the classical masters"))
    relaxation: object = field(default=1.0, metadata=key(
        "DR: λ of the relaxed update u ← u + λ (w − b̂), or `auto` (chosen from a probe where it helps)", "1",
        "number in (0, 2) or auto"))
    anderson: int = field(default=0, metadata=key("DR: Anderson acceleration window m (0: off)", "1",
                                                  f"integer 0..{ANDERSON_MAX}"))
    anderson_memory: bool = field(default=False, metadata=key(
        "DR: keep the Anderson differences across macro-steps (needs `anderson` >= 1)", type="boolean"))
    anderson_extrapolate: bool = field(default=False, metadata=key(
        "DR: commit the Anderson combination of the responses as b* (needs `anderson` >= 1)", type="boolean"))
    start: str = field(default="auto", metadata=key(
        "DR: the start u^{n,0} of the inner loop: `paper` (P bⁿ, Algorithm 1), `extrapolated` (P (2 bⁿ − bⁿ⁻¹)), "
        "`previous` (the waves committed at the previous macro-step), or `auto`: `previous` under the energy "
        "ledger, `paper` under the other guards, `extrapolated` over the varying step of the tolerance mode",
        type="auto | paper | extrapolated | previous"))
    warm_start: bool = field(default=None, metadata=key(
        "DR: `true` is `start: extrapolated`, `false` is `start: paper`", type="boolean", default="none"))
    options: str = field(default="manual", metadata=key(
        "DR: `auto` chooses γ, the relaxation and the Anderson window from the scene (Masters and DR); "
        "`manual` keeps what the file gives", type="manual | auto"))
    tolerance: float = field(default=None, metadata=key(
        "the tolerance mode: the macro-step varies (`dt` is the first step), chosen per step from a local error "
        "estimate against this relative tolerance (Masters and DR, choosing a tolerance); runs step by step on "
        "the Python route", "1", "number > 0 or null", "none (fixed dt)"))
    atol: float = field(default=None, metadata=key(
        "the tolerance mode's absolute tolerance, added to tolerance × the size of each interface variable",
        "the port variables' units", "number > 0 or null", "0.1 × tolerance × the largest watched variable's size"))
    dt_min: float = field(default=None, metadata=key(
        "the tolerance mode's smallest macro-step (a step at dt_min is accepted whatever its estimate)", "s",
        "number > 0 or null", "dt / 1000"))
    dt_max: float = field(default=None, metadata=key(
        "the tolerance mode's largest macro-step", "s", "number > 0 or null", "(T − start_time) / 10"))
    output_step: float = field(default=None, metadata=key(
        "the tolerance mode: steps also end on the times start_time + k output_step (no interpolation: "
        "trajectory.csv holds those points among the accepted ones)", "s", "number > 0 or null", "none"))
    estimate: str = field(default="auto", metadata=key(
        "the tolerance mode's error estimate: `predictor` (the committed interface against its extrapolation, "
        "no extra FMU call), `coupling` (explicit, gauss-seidel: each FMU made again with the other end of its "
        "held inputs, one doStep more), `doubling` (one step of h against two of h/2, as MasterSim and PyFMI); "
        "`auto`: `coupling` for the FMUs set up with a tolerance where the master holds its inputs, else "
        "`predictor`", type="auto | predictor | coupling | doubling"))
    fmu_tolerance: object = field(default="auto", metadata=key(
        "the largest set-up tolerance of each FMU set up with one (its subsystem's `tolerance`, else its "
        "DefaultExperiment's); a looser one is tightened to it. `auto`: " + f"{FMU_SHARE:g}" + " × tolerance in the "
        "tolerance mode, so the FMUs' own error stays below the one asked for; none with a fixed step",
        "1", "auto | number > 0 | null"))


@dataclass
class CertificateConfig:
    augmented: bool = field(default=True, metadata=key(
        "compute Theorem 1's augmented residual at the sampled steps (needs every H)", type="boolean"))
    fne_pairs: int = field(default=8, metadata=key(
        "random pairs per subsystem on which Condition 1's FNE margin is sampled (0: none)", "1", "integer >= 0"))
    fne_seed: int = field(default=1, metadata=key("seed of the random pairs", "1", "integer"))
    fne_scale: float = field(default=0.1, metadata=key(
        "spread of the random pairs, relative to the size of the incident wave", "1", "number > 0"))
    every: object = field(default="auto", metadata=key(
        "sample at the macro-steps n with n % every == 0; `auto`: as often as the master's own FMU evaluations "
        "allow (max(1, ⌈(2 fne_pairs + 4) / (K + 1)⌉) for DR)", "steps", "integer >= 1 or auto"))


@dataclass
class Scenario:
    name: str = field(metadata=key("the scenario's name, in summary.json and the figures", type="text",
                                   default="the file's name without its extension"))
    source: str
    dt: float = field(metadata=key("the macro-step Δt", "s", "number > 0",
                                   "the smallest DefaultExperiment stepSize of the FMUs"))
    T: float = field(metadata=key("the stop time; the run makes (T − start_time) / dt steps, a whole number", "s",
                                  "number > start_time", "the largest DefaultExperiment stopTime of the FMUs"))
    gamma: object = field(metadata=key(
        "the scattering impedance γ of the wave variables (Choosing γ); a subsystem's own `gamma` overrides it",
        IMPEDANCE, "number > 0, or auto | auto-retune | fastest | fast-unsafe",
        "`auto` where there is a power bond; unused without one"))
    subsystems: list = field(metadata=key("the FMUs, one entry per subsystem (keys below)",
                                          type="mapping NAME: subsystem", default="required"))
    couplings: list = field(metadata=key(
        "the power bonds, each a lossless coupling of port channels (keys below); left out: a system of "
        "signals only", type="list", default="none"))
    master: MasterConfig = field(metadata=key("the master and its settings (keys below)", type="mapping",
                                              default="see below"))
    certificates: CertificateConfig = field(metadata=key(
        "the sampled certificates: Condition 1 margins and Theorem 1's residual (keys below)", type="mapping",
        default="see below"))
    outputs: dict = field(metadata=key(
        "the columns of trajectory.csv: a mapping COLUMN: SUBSYSTEM.variable records exactly those; a list of "
        "glob patterns (`[A.*, B.y]`) narrows the default columns", type="mapping or list",
        default="every output and every input a signal drives, named SUBSYSTEM.variable"))
    error: list = field(metadata=key(
        "the output columns of the error norm against the monolithic reference (the `error` column, max_error, "
        "...)", type="list of columns", default="none: no error figures"))
    description: str = field(default="", metadata=key(
        "free text: one line saying what the scene is (`wavecosim examples` shows it)", type="text"))
    fne_watch: bool = field(default=True, metadata=key(
        "the Condition 1 watch: estimates each frozen map's FNE margin from the inner iterates and warns once "
        "when it goes negative", type="boolean"))
    signal_subsystems: list = field(default_factory=list)     # subsystems without a port (signals only)
    sources: list = field(default_factory=list, metadata=key(
        "time tables signals can read, by name (keys below)", type="mapping NAME: source", default="none"))
    signals: list = field(default_factory=list, metadata=key(
        "causal connections, each held over a macro-step (keys below)", type="list", default="none"))
    start_time: float = field(default=0.0, metadata=key(
        "t₀ of the grid t_n = t₀ + n·dt, given to every FMU's set-up", "s", "number",
        "the start time the FMUs' DefaultExperiments agree on, else 0"))
    growth_bound: float = field(default=GROWTH_BOUND, metadata=key(
        "a recorded Real output beyond this many times the outputs' initial scale (their largest magnitude at "
        "the start, at least 1) stops the run with a NumericalError; null: no bound (non-finite values still "
        "stop it)", "1", "number > 1 or null"))
    output_patterns: list = field(default_factory=list)       # globs narrowing the recorded columns
    times_from: dict = field(default_factory=dict)            # {start_time, dt, T: where each value came from}
    order: list = field(default_factory=list)                 # every subsystem's name, in the file's order
    step_timeout: float = field(default=None, metadata=key(
        "seconds one call into an FMU may take before the run stops as timed out (`--step-timeout`)", "s",
        "number > 0 or null", "no limit"))

    @property
    def n_steps(self):
        return int(round((self.T - self.start_time) / self.dt))

    def times_line(self):
        """`dt=0.001 (its origin) start=0.0 (...) T=1.0 (...)`: the grid and where each value came from."""
        return " ".join(f"{label}={value}" + (f" ({self.times_from[key]})" if key in self.times_from else "")
                        for key, label, value in (("dt", "dt", self.dt), ("start_time", "start", self.start_time),
                                                  ("T", "T", self.T)))

    def with_master(self, where="master", **changes):
        """A copy with master settings changed; a master the system cannot run is refused (`where`
        names the option in the message)."""
        changed = replace(self, master=replace(self.master, **changes))
        check_master(changed.master.algorithm, changed.couplings, lambda msg: _fail(where, msg))
        return changed

    def with_changes(self, where="options", **changes):
        """A copy with top-level values changed (dt, T, gamma), checked like the file's own."""
        changed = replace(self, **changes)
        check_whole_steps(changed.T, changed.dt, lambda msg: _fail(where, msg), changed.start_time)
        return changed


def default_master(couplings):
    """DR where power bonds make it possible; the explicit (Jacobi) master where there are none."""
    return "dr" if couplings else SIGNALS_MASTER


def check_master(algorithm, couplings, fail):
    """A system without power bonds has nothing for an iterating or wave master to work on: only the
    explicit master runs it; `fail(message)` raises."""
    if not couplings and algorithm != SIGNALS_MASTER:
        fail(f"{algorithm} couples power bonds, and this system has none (no couplings); it runs with "
             f"{SIGNALS_MASTER}")


def _fail(where, message):
    raise ConfigError(f"{where}: {message}")


MAX_GRID_STEPS = 10 ** 15      # beyond this, n dt no longer tells the steps apart (and no run ends)


def check_whole_steps(T, dt, fail, t0=0.0):
    """The stop time T must be a whole number (>= 1) of macro-steps dt after the start time t0, finite
    and at most MAX_GRID_STEPS of them; `fail(message)` raises."""
    if not (math.isfinite(dt) and dt > 0):
        fail(f"dt must be a finite number > 0, got {dt!r}")
    if not math.isfinite(T):
        fail(f"T must be a finite number, got {T!r}")
    span, after = T - t0, f" after the start time {t0:g}" if t0 else ""
    if not span / dt <= MAX_GRID_STEPS:
        fail(f"dt = {dt!r} is too small for T = {T!r}{after} ({span / dt:.3g} steps; at most {MAX_GRID_STEPS:.0e})")
    if span < dt:
        fail(f"T must be at least one step dt = {dt}{after}, got {T}")
    if abs(span / dt - round(span / dt)) > 1e-9 * (span / dt):
        fail(f"T must be a whole number of steps dt = {dt}{after}, got {T}")


class _Checker:
    """Walks a parsed YAML mapping, reporting the first bad key as `file: key.path: problem`."""

    def __init__(self, source):
        self.source = source

    def fail(self, path, message):
        message = brief_text(message)
        raise ConfigError(f"{self.source}: {path}: {message}" if path else f"{self.source}: {message}")

    def mapping(self, value, path, allowed, required=()):
        if not isinstance(value, dict):
            self.fail(path, f"must be a mapping, got {type(value).__name__}")
        for key in value:
            if key not in allowed:
                where = f"{path}.{key}" if path else str(key)
                self.fail(where, f"unknown key (allowed: {', '.join(allowed)})")
        for key in required:
            if key not in value:
                self.fail(f"{path}.{key}" if path else key, "missing required key")
        return value

    def number(self, value, path, positive=False, minimum=None):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(path, f"must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            self.fail(path, f"must be finite, got {value!r}")
        if positive and value <= 0:
            self.fail(path, f"must be > 0, got {value!r}")
        if minimum is not None and value < minimum:
            self.fail(path, f"must be >= {minimum}, got {value!r}")
        return value

    def integer(self, value, path, minimum=INT32[0], maximum=INT32[1]):
        """An integer within [minimum, maximum]: by default a C int's range, as the kernel takes it."""
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(path, f"must be an integer, got {value!r}")
        if value < minimum:
            self.fail(path, f"must be >= {minimum}, got {value!r}")
        if value > maximum:
            self.fail(path, f"must be <= {maximum}, got {value!r}")
        return value

    def string(self, value, path, choices=None):
        if not isinstance(value, str) or not value:
            self.fail(path, f"must be a non-empty string, got {value!r}")
        if choices and value not in choices:
            self.fail(path, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def boolean(self, value, path):
        if not isinstance(value, bool):
            self.fail(path, f"must be true or false, got {value!r}")
        return value

    def names(self, value, path):
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
            self.fail(path, f"must be a list of variable names, got {value!r}")
        return list(value)

    def values(self, value, path):
        """Start values and parameters of any FMI type: numbers, true/false or strings (each is
        checked against the type its variable declares when the FMU is opened)."""
        value = value or {}
        self.mapping(value, path, list(value))
        return {str(k): v if isinstance(v, (bool, str)) or (isinstance(v, int) and not isinstance(v, bool))
                else self.number(v, f"{path}.{k}") for k, v in value.items()}


# The keys of `port:` (not dataclass fields: a port is kept as a mapping of lists); docs/scenario.md
# is generated from this table, with the dataclasses' keys.
PORT_KEYS = {
    "wave_in": key("wave port: the FMU's input of each channel's incident wave a", "sqrt(J)", "variable or list",
                   "`a`"),
    "wave_out": key("wave port: the FMU's output of each channel's outgoing wave b", "sqrt(J)", "variable or list",
                    "`b`"),
    "effort": key("the output holding each channel's effort e (a physical port: derived from physical_in, "
                  "physical_out and input)", "the port's effort unit", "variable or list", "`e`"),
    "flow": key("the output holding each channel's flow f (a physical port: derived like effort)",
                "the port's flow unit", "variable or list", "`f`"),
    "physical_in": key("each channel's physical input: the effort or the flow the FMU takes (a physical port, "
                       "with physical_out; on a wave port, the input of its physical mode)", type="variable or list",
                       default="none"),
    "physical_out": key("each channel's physical output; giving it makes the port physical (an FMU without a "
                        "wave mode, reached through the wave adapter)", type="variable or list", default="none"),
    "input": key("whether each channel's physical input is the effort or the flow (the output is the other)",
                 type="effort | flow, or a list", default="required with physical_out"),
    "sign": key("power into the FMU = sign · effort · flow, per channel (a physical port only)", "1",
                "1 | -1, or a list", "found by probing one doStep (a warning says which)"),
    "energy": key("the output holding the stored energy H (optional on a physical port: without it there is "
                  "no Condition 2 residual or Theorem 1 residual)", "J", "variable",
                  "`H` on a wave port; none on a physical port"),
}


def _physical_port(ck, path, port):
    """A physical port (an FMU without a wave mode): input and output variable, which of the two
    is the effort, and the sign s with power into the FMU = s e f (omitted: found by probing)."""
    for key in ("physical_in", "input"):
        if key not in port:
            ck.fail(f"{path}.{key}", "missing required key for a physical port (physical_out is given)")
    spec = {key: ck.names(port[key], f"{path}.{key}") for key in ("physical_in", "physical_out", "input")}
    for k in spec["input"]:
        ck.string(k, f"{path}.input", ("flow", "effort"))
    m = len(spec["physical_in"])
    for key in ("physical_out", "input"):
        if len(spec[key]) != m:
            ck.fail(f"{path}.{key}", f"has {len(spec[key])} entries but physical_in has {m} channels")
    pairs = list(zip(spec["physical_in"], spec["physical_out"], spec["input"]))
    spec["effort"] = [i if kind == "effort" else o for i, o, kind in pairs]
    spec["flow"] = [o if kind == "effort" else i for i, o, kind in pairs]
    for key in ("effort", "flow"):
        if key in port and ck.names(port[key], f"{path}.{key}") != spec[key]:
            ck.fail(f"{path}.{key}", f"must be {spec[key]} (from physical_in, physical_out and input), "
                                     f"got {port[key]!r}")
    if "sign" in port:
        signs = port["sign"] if isinstance(port["sign"], list) else [port["sign"]]
        if not all(not isinstance(v, bool) and v in (1, -1) for v in signs):
            ck.fail(f"{path}.sign", f"must be 1 or -1 per channel, got {port['sign']!r}")
        spec["sign"] = [float(v) for v in signs]
    for key in ("wave_in", "wave_out"):
        if key in port:
            spec[key] = ck.names(port[key], f"{path}.{key}")
    if "energy" in port:
        spec["energy"] = ck.string(port["energy"], f"{path}.energy")
    return spec


def _port(ck, path, port):
    """The port spec: wave-port keys with their defaults, or a physical port when physical_out is given."""
    if "physical_out" in port:
        spec = _physical_port(ck, path, port)
        m, first = len(spec["physical_in"]), "physical_in"
    else:
        if "sign" in port:
            ck.fail(f"{path}.sign", "only a physical port (with physical_out) takes a sign")
        spec = {
            "wave_in": ck.names(port.get("wave_in", ["a"]), f"{path}.wave_in"),
            "wave_out": ck.names(port.get("wave_out", ["b"]), f"{path}.wave_out"),
            "effort": ck.names(port.get("effort", ["e"]), f"{path}.effort"),
            "flow": ck.names(port.get("flow", ["f"]), f"{path}.flow"),
            "energy": ck.string(port.get("energy", "H"), f"{path}.energy"),
        }
        m, first = len(spec["wave_in"]), "wave_in"
        if "physical_in" in port:
            spec["physical_in"] = ck.names(port["physical_in"], f"{path}.physical_in")
        if "input" in port:
            kinds = ck.names(port["input"], f"{path}.input")
            for k in kinds:
                ck.string(k, f"{path}.input", ("flow", "effort"))
            spec["input"] = kinds
    for key in ("wave_in", "wave_out", "effort", "flow", "physical_in", "physical_out", "input", "sign"):
        if key in spec and len(spec[key]) != m:
            ck.fail(f"{path}.{key}", f"has {len(spec[key])} entries but {first} has {m} channels")
    return spec


def _subsystem(ck, name, raw, base_dir):
    path = f"subsystems.{name}"
    ck.mapping(raw, path, keys_of(SubsystemConfig), required=("fmu",))
    fmu = ck.string(raw["fmu"], f"{path}.fmu")
    spec = None                        # no port key: a signal-only subsystem unless a coupling names it
    if "port" in raw:
        spec = _port(ck, f"{path}.port", ck.mapping(raw["port"] or {}, f"{path}.port", PORT_KEYS))
    integers = raw.get("integers") or {}
    ck.mapping(integers, f"{path}.integers", list(integers))
    integers = {k: ck.integer(v, f"{path}.integers.{k}", minimum=INT32[0], maximum=INT32[1])
                for k, v in integers.items()}
    fmu_path = None
    if fmu.endswith(".fmu") or "/" in fmu:
        given = base_dir / fmu
        fmu_path = regular_file(given, lambda message: ConfigError(f"{ck.source}: {path}.fmu: {message}")) or \
            Path(os.path.abspath(given))
    quirks = ck.mapping(raw.get("quirks") or {}, f"{path}.quirks", QUIRK_KEYS)
    return SubsystemConfig(name=name, fmu=fmu, parameters=ck.values(raw.get("parameters"), f"{path}.parameters"),
                           start=ck.values(raw.get("start"), f"{path}.start"), integers=integers, port=spec,
                           fmu_path=fmu_path,
                           gamma=ck.number(raw["gamma"], f"{path}.gamma", positive=True) if "gamma" in raw else None,
                           tolerance=(ck.number(raw["tolerance"], f"{path}.tolerance", positive=True)
                                      if raw.get("tolerance") is not None else None),
                           substeps=ck.integer(raw.get("substeps", 1), f"{path}.substeps", minimum=1, maximum=MAX_SUBSTEPS),
                           quirks={k: ck.boolean(v, f"{path}.quirks.{k}") for k, v in quirks.items()} or None)


ENERGY_GUARDS = ("ledger", "monolithic", "off")


def _energy_guard(ck, value):
    """master.energy_guard: ledger, monolithic or off; true and false (old files, and YAML's
    unquoted on/off) mean monolithic and off."""
    if isinstance(value, bool):
        return "monolithic" if value else "off"
    return ck.string(value, "master.energy_guard", ENERGY_GUARDS)


PORT_REF = re.compile(r"^([A-Za-z_][\w-]*)(?:\[(\d+)\])?$")


def _coupling(ck, k, raw, subsystem_names):
    path = f"couplings[{k}]"
    ck.mapping(raw, path, keys_of(CouplingConfig), required=("type", "ports"))
    ctype = ck.string(raw["type"], f"{path}.type", COUPLING_TYPES)
    ports = raw["ports"]
    if not isinstance(ports, list) or not ports:
        ck.fail(f"{path}.ports", f"must be a non-empty list like [A, B] or [A[0], B[1]], got {ports!r}")
    for p in ports:
        m = PORT_REF.match(str(p))
        if not m:
            ck.fail(f"{path}.ports", f"{p!r} is not a port reference (NAME or NAME[channel])")
        if m.group(1) not in subsystem_names:
            ck.fail(f"{path}.ports", f"{p!r} names no subsystem (have: {', '.join(subsystem_names)})")
    c = CouplingConfig(type=ctype, ports=[str(p) for p in ports])
    if ctype in TAKES_RATIO:
        if "ratio" not in raw:
            ck.fail(f"{path}.ratio", f"missing required key for a {ctype}")
        c.ratio = ck.number(raw["ratio"], f"{path}.ratio")
        if c.ratio == 0:
            ck.fail(f"{path}.ratio", "must be non-zero")
    elif "ratio" in raw:
        ck.fail(f"{path}.ratio", "only a transformer or gyrator takes a ratio")
    if ctype == "dirac":
        for key in ("E", "F"):
            mat = raw.get(key)
            if not isinstance(mat, list) or not all(isinstance(r, list) for r in mat):
                ck.fail(f"{path}.{key}", "must be a matrix (a list of rows)")
            for i, row in enumerate(mat):
                if len(row) != len(mat[0]) or not row:
                    ck.fail(f"{path}.{key}[{i}]", f"has {len(row)} entries, row 0 has {len(mat[0])}: "
                                                  f"a matrix has rows of one length")
                for j, v in enumerate(row):
                    ck.number(v, f"{path}.{key}[{i}][{j}]")
        c.E, c.F = raw["E"], raw["F"]
    elif "E" in raw or "F" in raw:
        ck.fail(f"{path}", "E and F are only given for type dirac")
    return c


MAX_FILE_BYTES = 16 << 20      # bytes of a scenario file
MAX_DEPTH = 64                 # levels of nesting a scenario file may have (mappings and lists within each other)


class _SafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader (no Python tags such as !!python/object), refusing a key given twice and
    nesting deeper than MAX_DEPTH (refused while reading, before it can exhaust the stack)."""
    depth = 0

    def compose_node(self, parent, index):
        if self.depth >= MAX_DEPTH:
            raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_DEPTH} levels",
                                              self.peek_event().start_mark)
        self.depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


def _mapping_without_duplicates(loader, node):
    loader.flatten_mapping(node)
    seen = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            first = seen.get(key)
        except TypeError:              # unhashable key: construct_mapping below reports it
            continue
        if first is not None:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r} (first on line {first + 1})",
                                                    key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return loader.construct_mapping(node, deep=True)


_SafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping_without_duplicates)


def load_scenario(path=None, settings=None, changes=()) -> Scenario:
    """Read and validate a scenario file (the built-in default when path is None, an example by its
    name); `settings` (the command line's dt, T, start_time) stand for the values the file leaves
    out; `changes` are (key path, value) set in the file's mapping first (`--set`)."""
    path = Path(resolve(path)) if path else DEFAULT_CONFIG
    return parse_scenario(apply_overrides(load_raw(path), changes), str(path), path.parent, settings)


def load_raw(path) -> dict:
    """The YAML mapping of a scenario file, read safely, its repeats expanded, not yet checked."""
    path = Path(path)
    if regular_file(path, ConfigError, MAX_FILE_BYTES) is None:
        raise ConfigError(f"{path}: scenario file not found")
    try:
        raw = yaml.load(path.read_text(encoding="utf-8"), Loader=_SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else "?"
        raise ConfigError(f"{path}: not valid YAML ({where}: {getattr(exc, 'problem', exc)})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    check_expansion(raw, str(path))
    return expand_repeats(raw, _Checker(str(path)))         # so that --set sees every repeated entry


MAX_VALUES = 1_000_000         # values a scenario may hold once its anchors and aliases are expanded


def check_expansion(raw, source):
    """Refuse a YAML whose aliases expand to more than MAX_VALUES values (a "billion laughs" file), nest
    values deeper than MAX_DEPTH, or refer to themselves, counting each shared node once per use
    without expanding anything."""
    sizes, open_ = {}, set()

    def size(node, level=0):
        """(values, levels) of a node `level` levels down, each shared node measured once."""
        if not isinstance(node, (dict, list)):
            return 1, 0
        if level > MAX_DEPTH:
            return 1, MAX_DEPTH + 1
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in open_:
            raise ConfigError(f"{source}: an anchor refers to itself (a value that contains itself)")
        open_.add(key)
        total, height = 1, 0
        for child in (node.values() if isinstance(node, dict) else node):
            values, levels = size(child, level + 1)
            total, height = total + values, max(height, levels + 1)
            if total > MAX_VALUES or height > MAX_DEPTH:
                break
        open_.discard(key)
        sizes[key] = total, height
        return total, height

    total, height = size(raw)
    if height > MAX_DEPTH:
        raise ConfigError(f"{source}: its anchors and aliases nest values deeper than {MAX_DEPTH} levels")
    if total > MAX_VALUES:
        raise ConfigError(f"{source}: its anchors and aliases expand to more than {MAX_VALUES:,} values "
                          f"(refused before expanding it)")


def _master(ck, m, couplings) -> MasterConfig:
    ck.mapping(m, "master", keys_of(MasterConfig))
    master = MasterConfig(algorithm=default_master(couplings))
    if "algorithm" in m:
        master.algorithm = ck.string(m["algorithm"], "master.algorithm", ALGORITHMS)
        check_master(master.algorithm, couplings, lambda msg: ck.fail("master.algorithm", msg))
    if "K" in m:
        master.K = ck.integer(m["K"], "master.K", minimum=0)
    if m.get("eps") is not None:
        master.eps = ck.number(m["eps"], "master.eps", positive=True)
    if m.get("deadline_us") is not None:
        master.deadline_us = ck.number(m["deadline_us"], "master.deadline_us", positive=True)
    if "fast" in m:
        master.fast = ck.string(str(m["fast"]).lower(), "master.fast", ("auto", "true", "false"))
    if "energy_guard" in m:
        master.energy_guard = _energy_guard(ck, m["energy_guard"])
    if "threads" in m:
        master.threads = _threads(ck, m["threads"])
    _dr_options(ck, m, master)
    _step_control(ck, m, master)
    return master


def _step_control(ck, m, master):
    """The tolerance mode's keys (masters/adaptive.py)."""
    for name in ("tolerance", "atol", "dt_min", "dt_max", "output_step"):
        if m.get(name) is not None:
            setattr(master, name, ck.number(m[name], f"master.{name}", positive=True))
    if "estimate" in m:
        master.estimate = ck.string(m["estimate"], "master.estimate", ("auto", "predictor", "coupling", "doubling"))
    if "fmu_tolerance" in m:
        value = m["fmu_tolerance"]
        if isinstance(value, str) and value != "auto":
            ck.fail("master.fmu_tolerance", f"must be auto, null or a number > 0, got {value!r}")
        master.fmu_tolerance = None if value is None else \
            "auto" if value == "auto" else ck.number(value, "master.fmu_tolerance", positive=True)


def _threads(ck, value, path="master.threads"):
    """master.threads: `auto`, or a number of threads N >= 1 (kept as its text, like `auto`)."""
    text = str(value).strip()
    if text != "auto" and (isinstance(value, bool) or not text.isdigit() or int(text) < 1):
        ck.fail(path, f"must be auto or a number of threads >= 1, got {value!r}")
    return text if text == "auto" else str(int(text))


def threads_option(value, option="--threads"):
    """A command line's threads (auto or N), checked as master.threads."""
    return _threads(_Checker(option), value, "")


def _dr_options(ck, m, master):
    """The DR master's named options (wavecosim/masters/dr_options.py)."""
    if "relaxation" in m:
        lam = m["relaxation"]
        master.relaxation = "auto" if lam == "auto" else ck.number(lam, "master.relaxation", positive=True)
        if lam != "auto" and not master.relaxation < 2.0:
            ck.fail("master.relaxation", f"must be in (0, 2) or auto, got {lam!r}")
    if "anderson" in m:
        master.anderson = ck.integer(m["anderson"], "master.anderson", minimum=0)
        if master.anderson > ANDERSON_MAX:
            ck.fail("master.anderson", f"must be at most {ANDERSON_MAX}, got {master.anderson}")
    if "anderson_memory" in m:
        master.anderson_memory = ck.boolean(m["anderson_memory"], "master.anderson_memory")
    if "anderson_extrapolate" in m:
        master.anderson_extrapolate = ck.boolean(m["anderson_extrapolate"], "master.anderson_extrapolate")
    if "warm_start" in m:                                   # true is the extrapolated start
        master.start = "extrapolated" if ck.boolean(m["warm_start"], "master.warm_start") else "paper"
    if "start" in m:
        master.start = ck.string(m["start"], "master.start", ("auto", *STARTS))
    if "options" in m:
        master.options = ck.string(m["options"], "master.options", OPTION_MODES)
    for key in ("anderson_memory", "anderson_extrapolate"):
        if getattr(master, key) and not master.anderson:
            ck.fail(f"master.{key}", "needs an Anderson window (master.anderson >= 1)")


def _certificates(ck, c) -> CertificateConfig:
    ck.mapping(c, "certificates", keys_of(CertificateConfig))
    certs = CertificateConfig()
    if "augmented" in c:
        certs.augmented = ck.boolean(c["augmented"], "certificates.augmented")
    if "fne_pairs" in c:
        certs.fne_pairs = ck.integer(c["fne_pairs"], "certificates.fne_pairs", minimum=0)
    if "fne_seed" in c:
        certs.fne_seed = ck.integer(c["fne_seed"], "certificates.fne_seed", minimum=0)
    if "fne_scale" in c:
        certs.fne_scale = ck.number(c["fne_scale"], "certificates.fne_scale", positive=True)
    if "every" in c and c["every"] != "auto":
        certs.every = ck.integer(c["every"], "certificates.every (an integer >= 1 or auto)", minimum=1)
    return certs


def _outputs(ck, raw, names):
    """(columns {name: SUBSYSTEM.variable}, patterns, error columns): `outputs:` names its columns
    (a mapping) or narrows the default ones with glob patterns (a list); left out, every output."""
    outputs, patterns = raw.get("outputs") or {}, []
    if isinstance(outputs, list):
        patterns, outputs = output_patterns(outputs, lambda msg: ck.fail("outputs", msg)), {}
    ck.mapping(outputs, "outputs", list(outputs))
    for col, ref in outputs.items():
        if not isinstance(ref, str) or "." not in ref or ref.split(".", 1)[0] not in names:
            ck.fail(f"outputs.{col}", f"must be SUBSYSTEM.variable with a known subsystem, got {ref!r}")
        if str(col) == "time" or any(ch in str(col) for ch in NOT_IN_COLUMNS):
            ck.fail(f"outputs.{col}", "a column name cannot be `time` or hold a comma, quote or line break")
    error = raw.get("error", [])
    if not isinstance(error, list) or not all(isinstance(e, str) and (e in outputs or not outputs) for e in error):
        ck.fail("error", f"must list output columns (have: {', '.join(outputs) or 'every output'}), got {error!r}")
    return {str(c): r for c, r in outputs.items()}, patterns, list(error)


NOT_IN_COLUMNS = (",", '"', "\n", "\r")


def output_patterns(patterns, fail):
    """Glob patterns over the recorded columns (`outputs:` as a list, `--outputs`): non-empty text."""
    if isinstance(patterns, str):
        patterns = [patterns]
    if not isinstance(patterns, (list, tuple)) or not patterns or not all(isinstance(p, str) and p.strip()
                                                                          for p in patterns):
        fail(f"must be a list of patterns like [A.*, B.y], got {patterns!r}")
    return [p.strip() for p in patterns]


REPEAT_SECTIONS = ("subsystems", "couplings", "outputs", "error")
REPEAT_KEYS = {
    "repeat": key("stands for copies of the entry, one per i = a..b, with {i}, {i+1}, {2*i-1} ... replaced in "
                  "its key and strings (a string that is only such an expression becomes the number)",
                  type="mapping {INDEX: a..b}", default="none"),
    "value": key("the copy, when it is not a mapping (an output's SUBSYSTEM.variable, an error column)",
                 type="any", default="the entry without `repeat`"),
}
REPEAT_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")
INDEX_EXPR = re.compile(r"\{\s*(?:(\d+)\s*\*\s*)?([A-Za-z_]\w*)\s*(?:([+-])\s*(\d+))?\s*\}")


def expand_repeats(raw, ck):
    """N identical entries in a few lines: in subsystems, couplings, outputs and error, an entry
    that is a mapping with `repeat: {i: a..b}` stands for its copies for i = a..b (inclusive), with
    `{i}`, `{i+1}`, `{2*i-1}` ... replaced in its strings and in its key; a copy is the mapping
    without `repeat`, or its `value` when that is the only other key. Returns the expanded mapping."""
    if not isinstance(raw, dict):
        return raw
    out = dict(raw)
    for section in REPEAT_SECTIONS:
        node = raw.get(section)
        if isinstance(node, list):
            out[section] = [c for k, item in enumerate(node)
                            for _, c in _repeat_copies(ck, f"{section}[{k}]", None, item)]
        elif isinstance(node, dict):
            out[section] = {}
            for key, value in node.items():
                for new_key, c in _repeat_copies(ck, f"{section}.{key}", key, value):
                    if new_key in out[section]:
                        ck.fail(f"{section}.{key}", f"gives {new_key!r}, which is already given")
                    out[section][new_key] = c
    return out


def _repeat_copies(ck, where, key, item):
    """[(key, entry)] of one entry: itself, or its copies when it has a `repeat`."""
    if not isinstance(item, dict) or "repeat" not in item:
        return [(key, item)]
    spec = item["repeat"]
    if not isinstance(spec, dict) or len(spec) != 1:
        ck.fail(f"{where}.repeat", f"must be one index and its range, like {{i: 0..7}}, got {spec!r}")
    (var, span), = spec.items()
    m = REPEAT_RANGE.match(str(span))
    if not re.fullmatch(r"[A-Za-z_]\w*", str(var)) or not m or int(m.group(1)) > int(m.group(2)):
        ck.fail(f"{where}.repeat", f"must be one index and its range a..b (a <= b), like {{i: 0..7}}, got {spec!r}")
    body = {k: v for k, v in item.items() if k != "repeat"}
    body = body["value"] if set(body) == {"value"} else body
    values = range(int(m.group(1)), int(m.group(2)) + 1)
    return [(_substitute(key, var, i), _substitute(body, var, i)) for i in values]


def _substitute(node, var, i):
    """node with every {var}, {var+c}, {k*var-c} in its strings (keys too) replaced by its value at
    var = i; a string that is one such expression becomes the integer."""
    if isinstance(node, dict):
        return {_substitute(k, var, i): _substitute(v, var, i) for k, v in node.items()}
    if isinstance(node, list):
        return [_substitute(v, var, i) for v in node]
    if not isinstance(node, str):
        return node

    def value(m):
        if m.group(2) != var:
            return None
        offset = int(m.group(4) or 0) * (-1 if m.group(3) == "-" else 1)
        return int(m.group(1) or 1) * i + offset

    whole = INDEX_EXPR.fullmatch(node.strip())
    if whole and value(whole) is not None:
        return value(whole)
    return INDEX_EXPR.sub(lambda m: m.group(0) if value(m) is None else str(value(m)), node)


def parse_scenario(raw, source="<scenario>", base_dir=Path("."), settings=None) -> Scenario:
    """Check a parsed scenario mapping key by key; the first problem is a ConfigError naming the key.
    `settings` ({key: value}, None values ignored; the command line's dt, T, start_time) stand for
    top-level values the file leaves out, before the FMUs' DefaultExperiment is asked (the values
    the file gives are replaced afterwards, by api.with_overrides)."""
    ck = _Checker(source)
    raw = expand_repeats(raw, ck)
    ck.mapping(raw, "", keys_of(Scenario), required=("subsystems",))
    options = {k: v for k, v in (settings or {}).items() if v is not None and raw.get(k) is None}
    raw = {**raw, **options}
    subs = raw["subsystems"]
    ck.mapping(subs, "subsystems", list(subs) if isinstance(subs, dict) else [])
    if len(subs) < 1:
        ck.fail("subsystems", "must name at least one subsystem")
    subsystems = [_subsystem(ck, str(n), s, base_dir) for n, s in subs.items()]
    names = [s.name for s in subsystems]
    start_time, dt, T, times_from = _times(ck, raw, subsystems, options)
    couplings = raw.get("couplings") or []
    if not isinstance(couplings, list):
        ck.fail("couplings", "must be a list of couplings (or left out: a system without power bonds)")
    couplings = [_coupling(ck, k, c, names) for k, c in enumerate(couplings)]
    gamma = _gamma(ck, raw.get("gamma"), couplings)
    subsystems, signal_subsystems = _split_signal_only(subsystems, couplings)
    sources = _sources(ck, raw.get("sources"), names, base_dir)
    signals = _signals(ck, raw.get("signals"), subsystems + signal_subsystems, sources)
    master, certs = _master(ck, raw.get("master") or {}, couplings), _certificates(ck, raw.get("certificates") or {})
    outputs, patterns, error = _outputs(ck, raw, names)
    return Scenario(name=str(raw.get("name", Path(source).stem)), source=source, dt=dt, T=T, gamma=gamma,
                    subsystems=subsystems, couplings=couplings, master=master, certificates=certs,
                    outputs=outputs, error=error, description=str(raw.get("description", "")),
                    fne_watch=ck.boolean(raw.get("fne_watch", True), "fne_watch"),
                    signal_subsystems=signal_subsystems, sources=sources, signals=signals,
                    output_patterns=patterns, order=names, start_time=start_time, times_from=times_from,
                    growth_bound=_growth_bound(ck, raw.get("growth_bound", GROWTH_BOUND)),
                    step_timeout=(ck.number(raw["step_timeout"], "step_timeout", positive=True)
                                  if raw.get("step_timeout") is not None else None))


def _growth_bound(ck, value):
    """growth_bound: a number > 1, or null (no bound on growth; non-finite values still stop a run)."""
    if value is None:
        return math.inf
    bound = ck.number(value, "growth_bound", positive=True)
    if bound <= 1:
        ck.fail("growth_bound", f"must be > 1 (a factor over the outputs' initial scale) or null, got {value!r}")
    return bound


def _times(ck, raw, subsystems, options=()):
    """(start_time, dt, T, where each came from): as given (in the file, or among the `options` of
    the command line), else from the FMUs' DefaultExperiments (the start time they agree on, else 0;
    the smallest stepSize; the largest stopTime); dt or T that nothing gives is refused in one line
    naming it. T is the stop time: the run makes (T - start_time) / dt steps."""
    found = from_fmus(subsystems, [k for k in ("start_time", "dt", "T") if raw.get(k) is None])
    origin = {key: f" ({found[key][1]})" for key in found}
    times_from = {"start_time": "the default 0", **{k: v for k, (_, v) in found.items()},
                  **{k: "the command line" if k in options else "the scenario file" for k in ("start_time", "dt", "T")
                     if raw.get(k) is not None}}
    if "start_time" in raw:
        start = ck.number(raw["start_time"], "start_time")
    elif found.get("start_time", (0.0,))[0] is None:
        ck.fail("start_time", f"not given, and the FMUs' DefaultExperiment start times differ "
                              f"({found['start_time'][1]}); give start_time or --start-time")
    else:
        start = found.get("start_time", (0.0,))[0]
    for key, option in (("dt", "stepSize"), ("T", "stopTime")):
        if raw.get(key) is None and key not in found:
            ck.fail(key, f"not given, and no FMU gives a DefaultExperiment {option}; give {key}: or --{key}")
    dt = ck.number(raw["dt"] if raw.get("dt") is not None else found["dt"][0], "dt", positive=True)
    T = ck.number(raw["T"] if raw.get("T") is not None else found["T"][0], "T", positive=start == 0.0)
    if T <= start:
        ck.fail("T", f"the stop time must be after the start time {start:g}, got {T:g}{origin.get('T', '')}")
    check_whole_steps(T, dt, lambda msg: ck.fail("T", msg.removeprefix("T ") + origin.get("T", "")), start)
    return start, dt, T, times_from


def _gamma(ck, gamma, couplings):
    """gamma: a number > 0 or a mode; left out, `auto` where there is a power bond, and None (nothing
    has waves) where there is none."""
    if gamma is None:
        return "auto" if couplings else None
    if isinstance(gamma, str):
        return ck.string(gamma, "gamma", GAMMA_MODES)
    return ck.number(gamma, "gamma", positive=True)


def _split_signal_only(subsystems, couplings):
    """(subsystems with a port, signal-only subsystems): a subsystem without `port:` that a coupling
    names gets the default wave port (our FMUs); one that no coupling names has no port."""
    coupled = {PORT_REF.match(p).group(1) for c in couplings for p in c.ports}
    for s in subsystems:
        if s.port is None and s.name in coupled:
            s.port = _port(_Checker("<default port>"), f"subsystems.{s.name}.port", {})
    return [s for s in subsystems if not s.signal_only], [s for s in subsystems if s.signal_only]


INTERPOLATIONS = ("hold", "linear")


BOOLEAN_WORDS = {"true": True, "false": False}


def _cell(text):
    """One value of a CSV table: a number, or true/false (any case) for a Boolean; None otherwise."""
    word = BOOLEAN_WORDS.get(text.strip().lower())
    if word is not None:
        return word
    try:
        return float(text)
    except ValueError:
        return None


def _read_table(ck, path, csv_path):
    """(times, {column: values}) of a CSV time table as the FMI cross-check files write them: a
    header (names may be quoted), first column `time`, numbers or true/false, times that never
    decrease (a repeated time is an event: the rows before and after it)."""
    where = lambda: f"{path}.csv"                      # noqa: E731
    try:
        with open(csv_path, newline="") as f:
            rows = [r for r in csv.reader(f, skipinitialspace=True) if r and any(x.strip() for x in r)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        ck.fail(where(), f"cannot read {csv_path}: {exc}")
    if not rows or rows[0][0].strip().lower() != "time":
        ck.fail(where(), f"{csv_path.name}: the first column of the header must be `time`, got "
                         f"{rows[0][0].strip() if rows else 'an empty file'!r}")
    header = [h.strip() for h in rows[0]]
    if len(rows) < 2 or len(header) < 2:
        ck.fail(where(), f"{csv_path.name}: needs a `time` column, at least one value column and one row")
    data = []
    for k, row in enumerate(rows[1:], start=2):
        values = [_cell(x) for x in row]
        if None in values:
            ck.fail(where(), f"{csv_path.name}: line {k} is not all numbers or true/false: {','.join(row)}")
        if len(values) != len(header) or not all(isinstance(v, bool) or math.isfinite(v) for v in values):
            ck.fail(where(), f"{csv_path.name}: line {k} needs {len(header)} finite numbers, got {len(values)}")
        if isinstance(values[0], bool):
            ck.fail(where(), f"{csv_path.name}: line {k}: the time must be a number, got {row[0]!r}")
        if data and values[0] < data[-1][0]:
            ck.fail(where(), f"{csv_path.name}: times must not decrease, line {k} has {values[0]!r} after "
                             f"{data[-1][0]!r}")
        data.append(values)
    columns = {h: tuple(row[j] for row in data) for j, h in enumerate(header) if j}
    for name, values in columns.items():
        if len({isinstance(v, bool) for v in values}) > 1:
            ck.fail(where(), f"{csv_path.name}: column {name} mixes true/false and numbers")
    return tuple(row[0] for row in data), columns


MAX_TABLE_BYTES = 100_000_000        # bytes of a CSV time table (an --input file, a source): read whole into memory


def input_file(csv_path, where):
    """The resolved path of a CSV time table (`where` names it: the option or the key), a regular file
    of at most MAX_TABLE_BYTES, else a one-line ConfigError."""
    found = regular_file(csv_path, lambda message: ConfigError(f"{where}: {message}"), MAX_TABLE_BYTES)
    if found is None:
        raise ConfigError(f"{where}: cannot read {csv_path}: file not found")
    return found


def _sources(ck, raw, subsystem_names, base_dir):
    """sources: {NAME: {csv: FILE, interpolation: hold | linear}}, FILE relative to the scenario."""
    raw = raw or {}
    ck.mapping(raw, "sources", list(raw))
    sources = []
    for name, spec in raw.items():
        path = f"sources.{name}"
        if name in subsystem_names:
            ck.fail(path, "is also the name of a subsystem")
        ck.mapping(spec, path, keys_of(SourceConfig), required=("csv",))
        csv_path = input_file(base_dir / ck.string(spec["csv"], f"{path}.csv"), f"{ck.source}: {path}.csv")
        how = ck.string(spec.get("interpolation", "hold"), f"{path}.interpolation", INTERPOLATIONS)
        times, columns = _read_table(ck, path, csv_path)
        sources.append(SourceConfig(str(name), str(csv_path), how, times, columns))
    return sources


def _endpoint(ck, ref, path, subsystems, sources, target):
    """A signal's end, SUBSYSTEM.variable or (a `from` only) SOURCE.column; the FMU variable is
    checked when the FMU is opened."""
    name, _, var = ref.partition(".") if isinstance(ref, str) else ("", "", "")
    if not var:
        ck.fail(path, f"must be SUBSYSTEM.variable{'' if target else ' or SOURCE.column'}, got {ref!r}")
    source = next((s for s in sources if s.name == name), None)
    if source is not None and not target:
        if var not in source.columns:
            ck.fail(path, f"source {name} has no column {var!r} (have: {', '.join(source.columns)})")
        return
    sub = next((s for s in subsystems if s.name == name), None)
    if sub is None:
        known = [s.name for s in subsystems] + ([] if target else [s.name for s in sources])
        ck.fail(path, f"{ref!r} names no subsystem{'' if target else ' or source'} (have: {', '.join(known)})")
    if target and var in sub.start:
        ck.fail(path, f"{ref} is driven by a signal, so it cannot also have a start value "
                      f"(subsystems.{name}.start.{var})")
    port_vars = [v for key in ("physical_in", "physical_out", "wave_in", "wave_out") for v in (sub.port or {}).get(key, [])]
    if target and var in port_vars:
        ck.fail(path, f"{ref} is a port variable of {name}, so a signal cannot drive it")


def _signals(ck, raw, subsystems, sources):
    """signals: [{from: A.y, to: B.u, factor: 1.0, offset: 0.0}, ...]; each input driven at most once."""
    raw = raw or []
    if not isinstance(raw, list):
        ck.fail("signals", f"must be a list of {{from, to}} connections, got {raw!r}")
    signals, driven = [], {}
    for k, spec in enumerate(raw):
        path = f"signals[{k}]"
        ck.mapping(spec, path, keys_of(SignalConfig), required=("from", "to"))
        _endpoint(ck, spec["from"], f"{path}.from", subsystems, sources, target=False)
        _endpoint(ck, spec["to"], f"{path}.to", subsystems, sources, target=True)
        if spec["to"] in driven:
            ck.fail(f"{path}.to", f"{spec['to']} is already driven by signals[{driven[spec['to']]}]")
        driven[spec["to"]] = k
        signals.append(SignalConfig(spec["from"], spec["to"],
                                    ck.number(spec.get("factor", 1.0), f"{path}.factor"),
                                    ck.number(spec.get("offset", 0.0), f"{path}.offset")))
    return signals


# Every mapping of the scenario file and where its keys are declared (docs/scenario.md).
SECTIONS = (("", Scenario), ("subsystems.NAME", SubsystemConfig), ("subsystems.NAME.port", PORT_KEYS),
            ("couplings[i]", CouplingConfig), ("master", MasterConfig), ("certificates", CertificateConfig),
            ("sources.NAME", SourceConfig), ("signals[i]", SignalConfig),
            (f"an entry of {', '.join(REPEAT_SECTIONS)}", REPEAT_KEYS))


def key_reference():
    """[(section, [(key, type, default, unit, meaning)])] of every key the scenario file accepts."""
    def default(f, meta):
        if meta["default"] is not None or f is None:
            return meta["default"] or ""
        value = f.default_factory() if f.default_factory is not MISSING else f.default
        if value is None or value == "":
            return "none" if value is None else '`""`'
        return f"`{str(value).lower() if isinstance(value, bool) else value}`"
    out = []
    for path, where in SECTIONS:
        declared = where.items() if isinstance(where, dict) else [(k, f.metadata) for k, f in file_keys(where)]
        found = {k: f for k, f in file_keys(where)} if not isinstance(where, dict) else {}
        out.append((path, [(k, meta["type"], default(found.get(k), meta), meta["unit"], meta["doc"])
                           for k, meta in declared]))
    return out
