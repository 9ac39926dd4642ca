"""Scenario files: read YAML safely, check every key, and return a plain validated Scenario.

Every problem becomes a ConfigError whose one line names the file and the key path.
"""
import csv
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from ..errors import ConfigError
from ..examples import DEFAULT
from ..core.gamma import MODES as GAMMA_MODES
from ..core.interconnection import COUPLINGS, TAKES_RATIO
from ..masters import ALGORITHMS
from ..masters.dr_options import ANDERSON_MAX, OPTION_MODES, STARTS
from .experiment import from_fmus

DEFAULT_CONFIG = DEFAULT
COUPLING_TYPES = tuple(COUPLINGS)
SIGNALS_MASTER = "explicit"            # the master of a system without power bonds


@dataclass
class SubsystemConfig:
    name: str
    fmu: str
    parameters: dict
    start: dict
    integers: dict
    port: dict
    fmu_path: Path = None
    gamma: float = None
    tolerance: float = None            # passed to setupExperiment; None: the FMU's DefaultExperiment tolerance

    @property
    def signal_only(self):
        """No port: the subsystem only exchanges signals (stepped once per macro-step, never frozen)."""
        return self.port is None


@dataclass
class SourceConfig:
    """A time table (CSV with a header, first column `time`): the value at t_n per column."""
    name: str
    csv: str
    interpolation: str                 # hold (the value at the last time <= t_n) | linear
    times: tuple                       # never decreasing; a time given twice is an event
    columns: dict                      # {column: tuple of values (floats, or bools), one per time}


@dataclass
class SignalConfig:
    """A causal connection, held over each macro-step: to = factor * from + offset (SSP LinearTransformation)."""
    source: str                        # SUBSYSTEM.variable or SOURCE.column
    target: str                        # SUBSYSTEM.variable (an input)
    factor: float = 1.0
    offset: float = 0.0


@dataclass
class CouplingConfig:
    type: str
    ports: list
    ratio: float = None
    E: list = None
    F: list = None


@dataclass
class MasterConfig:
    algorithm: str = "dr"
    K: int = 50
    eps: float = None
    deadline_us: float = None
    fast: str = "auto"
    threads: str = "auto"
    energy_guard: str = None           # ledger | monolithic | off (true/false of old files); None: the master's default
    relaxation: object = 1.0           # DR: lambda in (0, 2) of line 12, or "auto" (masters/dr_options.py)
    anderson: int = 0                  # DR: Anderson window m (0: off)
    anderson_memory: bool = False      # DR: keep the Anderson differences across macro-steps
    anderson_extrapolate: bool = False  # DR: b^* the Anderson combination of the responses
    start: str = "auto"                # DR: u^{n,0}, one of dr_options.STARTS or auto (masters/dr_options.py)
    options: str = "manual"            # DR: auto chooses gamma, relaxation and Anderson from the scene (dr_options.py)


@dataclass
class CertificateConfig:
    augmented: bool = True
    fne_pairs: int = 8
    fne_seed: int = 1
    fne_scale: float = 0.1
    every: object = "auto"              # sample at steps n % every == 0: an integer >= 1, or "auto"


@dataclass
class Scenario:
    name: str
    source: str
    dt: float
    T: float
    gamma: object                      # a number, a mode, or None (no power bond: nothing has waves)
    subsystems: list
    couplings: list
    master: MasterConfig
    certificates: CertificateConfig
    outputs: dict
    error: list
    description: str = ""
    fne_watch: bool = True
    signal_subsystems: list = field(default_factory=list)     # subsystems without a port (signals only)
    sources: list = field(default_factory=list)               # SourceConfig
    signals: list = field(default_factory=list)               # SignalConfig
    start_time: float = 0.0                                   # t_0: the grid is t_n = t_0 + n dt; T is the stop time
    output_patterns: list = field(default_factory=list)       # globs narrowing the recorded columns
    order: list = field(default_factory=list)                 # every subsystem's name, in the file's order

    @property
    def n_steps(self):
        return int(round((self.T - self.start_time) / self.dt))

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


def check_whole_steps(T, dt, fail, t0=0.0):
    """The stop time T must be a whole number (>= 1) of macro-steps dt after the start time t0;
    `fail(message)` raises."""
    span, after = T - t0, f" after the start time {t0:g}" if t0 else ""
    if span < dt:
        fail(f"T must be at least one step dt = {dt}{after}, got {T}")
    if abs(span / dt - round(span / dt)) > 1e-9 * (span / dt):
        fail(f"T must be a whole number of steps dt = {dt}{after}, got {T}")


class _Checker:
    """Walks a parsed YAML mapping, reporting the first bad key as `file: key.path: problem`."""

    def __init__(self, source):
        self.source = source

    def fail(self, path, message):
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

    def integer(self, value, path, minimum=None):
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(path, f"must be an integer, got {value!r}")
        if minimum is not None and value < minimum:
            self.fail(path, f"must be >= {minimum}, got {value!r}")
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


PORT_KEYS = ("wave_in", "wave_out", "effort", "flow", "physical_in", "physical_out", "input", "sign", "energy")


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
    ck.mapping(raw, path, ("fmu", "parameters", "start", "integers", "port", "gamma", "tolerance"), required=("fmu",))
    fmu = ck.string(raw["fmu"], f"{path}.fmu")
    spec = None                        # no port key: a signal-only subsystem unless a coupling names it
    if "port" in raw:
        spec = _port(ck, f"{path}.port", ck.mapping(raw["port"] or {}, f"{path}.port", PORT_KEYS))
    integers = raw.get("integers") or {}
    ck.mapping(integers, f"{path}.integers", list(integers))
    integers = {k: ck.integer(v, f"{path}.integers.{k}") for k, v in integers.items()}
    fmu_path = None
    if fmu.endswith(".fmu") or "/" in fmu:
        fmu_path = (base_dir / fmu).resolve()
    return SubsystemConfig(name=name, fmu=fmu, parameters=ck.values(raw.get("parameters"), f"{path}.parameters"),
                           start=ck.values(raw.get("start"), f"{path}.start"), integers=integers, port=spec,
                           fmu_path=fmu_path,
                           gamma=ck.number(raw["gamma"], f"{path}.gamma", positive=True) if "gamma" in raw else None,
                           tolerance=(ck.number(raw["tolerance"], f"{path}.tolerance", positive=True)
                                      if raw.get("tolerance") is not None else None))


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
    ck.mapping(raw, path, ("type", "ports", "ratio", "E", "F"), required=("type", "ports"))
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
                for j, v in enumerate(row):
                    ck.number(v, f"{path}.{key}[{i}][{j}]")
        c.E, c.F = raw["E"], raw["F"]
    elif "E" in raw or "F" in raw:
        ck.fail(f"{path}", "E and F are only given for type dirac")
    return c


class _SafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader (no Python tags such as !!python/object), refusing a key given twice."""


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


def load_scenario(path=None, settings=None) -> Scenario:
    """Read and validate a scenario file (the built-in default when path is None); `settings` (the
    command line's dt, T, start_time) stand for the values the file leaves out."""
    path = Path(path) if path else DEFAULT_CONFIG
    return parse_scenario(load_raw(path), str(path), path.parent, settings)


def load_raw(path) -> dict:
    """The YAML mapping of a scenario file, read safely, its repeats expanded, not yet checked."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{path}: scenario file not found")
    try:
        raw = yaml.load(path.read_text(), Loader=_SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}" if mark else "?"
        raise ConfigError(f"{path}: not valid YAML ({where}: {getattr(exc, 'problem', exc)})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    return expand_repeats(raw, _Checker(str(path)))         # so that --set sees every repeated entry


def _master(ck, m, couplings) -> MasterConfig:
    ck.mapping(m, "master", ("algorithm", "K", "eps", "deadline_us", "fast", "threads", "energy_guard",
                             "relaxation", "anderson", "anderson_memory",
                             "anderson_extrapolate", "start", "warm_start", "options"))
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
        master.threads = ck.string(str(m["threads"]), "master.threads", ("auto", "1", "2"))
    _dr_options(ck, m, master)
    return master


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
    if "warm_start" in m:                                   # old files: true is the extrapolated start
        master.start = "extrapolated" if ck.boolean(m["warm_start"], "master.warm_start") else "paper"
    if "start" in m:
        master.start = ck.string(m["start"], "master.start", ("auto", *STARTS))
    if "options" in m:
        master.options = ck.string(m["options"], "master.options", OPTION_MODES)
    for key in ("anderson_memory", "anderson_extrapolate"):
        if getattr(master, key) and not master.anderson:
            ck.fail(f"master.{key}", "needs an Anderson window (master.anderson >= 1)")


def _certificates(ck, c) -> CertificateConfig:
    ck.mapping(c, "certificates", ("augmented", "fne_pairs", "fne_seed", "fne_scale", "every"))
    certs = CertificateConfig()
    if "augmented" in c:
        certs.augmented = ck.boolean(c["augmented"], "certificates.augmented")
    if "fne_pairs" in c:
        certs.fne_pairs = ck.integer(c["fne_pairs"], "certificates.fne_pairs", minimum=0)
    if "fne_seed" in c:
        certs.fne_seed = ck.integer(c["fne_seed"], "certificates.fne_seed")
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
    top = ("name", "description", "start_time", "dt", "T", "gamma", "subsystems", "couplings", "master",
           "certificates", "outputs", "error", "fne_watch", "sources", "signals")
    ck.mapping(raw, "", top, required=("subsystems",))
    raw = {**raw, **{k: v for k, v in (settings or {}).items() if v is not None and raw.get(k) is None}}
    subs = raw["subsystems"]
    ck.mapping(subs, "subsystems", list(subs) if isinstance(subs, dict) else [])
    if len(subs) < 1:
        ck.fail("subsystems", "must name at least one subsystem")
    subsystems = [_subsystem(ck, str(n), s, base_dir) for n, s in subs.items()]
    names = [s.name for s in subsystems]
    start_time, dt, T = _times(ck, raw, subsystems)
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
                    output_patterns=patterns, order=names, start_time=start_time)


def _times(ck, raw, subsystems):
    """(start_time, dt, T): as given, else from the FMUs' DefaultExperiments (the start time they
    agree on, else 0; the smallest stepSize; the largest stopTime); dt or T that nothing gives is
    refused in one line naming it. T is the stop time: the run makes (T - start_time) / dt steps."""
    found = from_fmus(subsystems, [k for k in ("start_time", "dt", "T") if raw.get(k) is None])
    origin = {key: f" ({found[key][1]})" for key in found}
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
    return start, dt, T


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


def _sources(ck, raw, subsystem_names, base_dir):
    """sources: {NAME: {csv: FILE, interpolation: hold | linear}}, FILE relative to the scenario."""
    raw = raw or {}
    ck.mapping(raw, "sources", list(raw))
    sources = []
    for name, spec in raw.items():
        path = f"sources.{name}"
        if name in subsystem_names:
            ck.fail(path, "is also the name of a subsystem")
        ck.mapping(spec, path, ("csv", "interpolation"), required=("csv",))
        csv_path = (base_dir / ck.string(spec["csv"], f"{path}.csv")).resolve()
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
        ck.mapping(spec, path, ("from", "to", "factor", "offset"), required=("from", "to"))
        _endpoint(ck, spec["from"], f"{path}.from", subsystems, sources, target=False)
        _endpoint(ck, spec["to"], f"{path}.to", subsystems, sources, target=True)
        if spec["to"] in driven:
            ck.fail(f"{path}.to", f"{spec['to']} is already driven by signals[{driven[spec['to']]}]")
        driven[spec["to"]] = k
        signals.append(SignalConfig(spec["from"], spec["to"],
                                    ck.number(spec.get("factor", 1.0), f"{path}.factor"),
                                    ck.number(spec.get("offset", 0.0), f"{path}.offset")))
    return signals
