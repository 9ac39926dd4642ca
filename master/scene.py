"""A scenario made concrete: FMU instances as Subsystems, stacked channels, the compiled coupling."""
import importlib.util
from dataclasses import dataclass

import numpy as np

from . import interconnection as ic
from .config import ROOT, Scenario
from .errors import ConfigError, CouplingError, FmuError
from .fmu import Fmu
from .frozen_port_map import PortSpec, Subsystem

_built = None


def builtin_fmus(log=None) -> dict:
    """{identifier: path} of the FMUs built from models/, rebuilt when their sources changed."""
    global _built
    if _built is None:
        spec = importlib.util.spec_from_file_location("wavecosim_fmu_build", ROOT / "fmus" / "build.py")
        build = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(build)
        try:
            _built = build.build_all(log=log or (lambda msg: None))
        except build.BuildError as exc:
            raise FmuError(str(exc).splitlines()[0]) from None
    return _built


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


def _port_spec(sub, fmu) -> PortSpec:
    p = dict(sub.port)
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
    for key in ("wave_in", "wave_out", "effort", "flow", "physical_in"):
        for name in p.get(key, []):
            if name not in fmu.variables:
                raise ConfigError(f"subsystems.{sub.name}.port.{key}: the FMU {fmu.path.name} has no variable "
                                  f"{name!r}")
    if p["energy"] not in fmu.variables:
        raise ConfigError(f"subsystems.{sub.name}.port.energy: the FMU {fmu.path.name} has no variable "
                          f"{p['energy']!r}")
    return PortSpec(wave_in=p["wave_in"], wave_out=p["wave_out"], effort=p["effort"], flow=p["flow"],
                    physical_in=p.get("physical_in", []), input_is_flow=[k == "flow" for k in p.get("input", [])],
                    energy=p["energy"])


@dataclass
class Scene:
    """Instantiated subsystems of one run and the compiled interconnection between their channels."""
    scenario: Scenario
    subsystems: list
    offsets: list
    E: np.ndarray
    F: np.ndarray
    gamma: float
    wave: bool
    gammas: list = None

    def channel_gammas(self, gamma=None):
        """Impedance of every channel: a scalar override, else each subsystem's own gamma."""
        per_sub = [gamma] * len(self.subsystems) if gamma is not None else (self.gammas or
                                                                            [self.gamma] * len(self.subsystems))
        return [g for g, s in zip(per_sub, self.subsystems) for _ in range(s.m)]

    @property
    def n_channels(self):
        return self.E.shape[0]

    def wave_map(self, gamma=None):
        return ic.compile_wave_map(self.E, self.F, self.channel_gammas(gamma),
                                   where=f"{self.scenario.source}: couplings")

    def input_map(self):
        """G with inputs = G outputs for physical masters, from E e + F f = 0 split by causality."""
        n = self.n_channels
        is_flow_in = np.zeros(n, bool)
        for s, off in zip(self.subsystems, self.offsets):
            if len(s.port.input_is_flow) != s.m or len(s.port.physical_in) != s.m:
                raise ConfigError(f"{self.scenario.source}: subsystems.{s.name}.port: physical_in and input (flow/effort) are needed "
                                  f"for a physical-domain master")
            is_flow_in[off:off + s.m] = s.port.input_is_flow
        # columns of the unknown inputs (flows where flow is input, efforts otherwise) and known outputs
        Mx = np.where(is_flow_in, self.F, self.E)
        My = np.where(is_flow_in, self.E, self.F)
        try:
            return -np.linalg.solve(Mx, My)
        except np.linalg.LinAlgError:
            raise CouplingError(f"{self.scenario.source}: couplings: the port causalities do not fit the "
                                f"interconnection (inputs cannot be computed from outputs)") from None

    def split(self, x):
        """Per-subsystem slices of a stacked channel vector."""
        return [x[off:off + s.m] for s, off in zip(self.subsystems, self.offsets)]

    def close(self):
        for s in self.subsystems:
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


def coupling_structure(scenario: Scenario, sizes):
    """Global E, F over all channels from the scenario's list of couplings."""
    names = [s.name for s in scenario.subsystems]
    index = {n: i for i, n in enumerate(names)}
    offsets = list(np.cumsum([0] + list(sizes))[:-1])
    blocks = []
    for k, c in enumerate(scenario.couplings):
        where = f"{scenario.source}: couplings[{k}]"
        groups = [_channels(p, index, offsets, sizes, where) for p in c.ports]
        chans = [ch for g in groups for ch in g]
        n = len(chans)
        if c.type == "equal_effort_opposite_flow":
            if len(groups) != 2 or len(groups[0]) != len(groups[1]):
                raise CouplingError(f"{where}: equal_effort_opposite_flow joins two ports of equal dimension, "
                                    f"got sizes {[len(g) for g in groups]}")
            E, F = ic.equal_effort_opposite_flow(len(groups[0]))
            blocks.append((k, E, F, chans))
        elif c.type in ("zero_junction", "one_junction"):
            if n < 2:
                raise CouplingError(f"{where}: a junction needs at least two channels")
            E, F = (ic.zero_junction if c.type == "zero_junction" else ic.one_junction)(n)
            blocks.append((k, E, F, chans))
        elif c.type in ("transformer", "gyrator"):
            if n != 2:
                raise CouplingError(f"{where}: a {c.type} joins exactly two scalar channels, got {n}")
            E, F = (ic.transformer if c.type == "transformer" else ic.gyrator)(c.ratio)
            blocks.append((k, E, F, chans))
        elif c.type in ("free_end", "clamped_end"):
            E, F = ic.free_end() if c.type == "free_end" else ic.clamped_end()
            blocks.extend((f"{k}.{j}", E, F, [ch]) for j, ch in enumerate(chans))
        else:
            E, F = np.asarray(c.E, float), np.asarray(c.F, float)
            if E.shape != (n, n) or F.shape != (n, n):
                raise CouplingError(f"{where}: E and F must be {n}x{n} for the {n} listed channels, got "
                                    f"{E.shape} and {F.shape}")
            ic.check_dirac(E, F, where)
            blocks.append((k, E, F, chans))
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


def build_scene(scenario: Scenario, wave=True, gamma=None, needs_rollback=True) -> Scene:
    """Instantiate every subsystem (wave or physical port mode) and compile the coupling."""
    g = gamma if gamma is not None else (scenario.gamma if not isinstance(scenario.gamma, str) else 0.4)
    subsystems, gammas = [], []
    try:
        for sub in scenario.subsystems:
            path = resolve_fmu(sub, scenario.source)
            g_sub = sub.gamma if (sub.gamma is not None and gamma is None) else g
            gammas.append(g_sub)
            reals = {**sub.parameters, **sub.start, "gamma": g_sub}
            integers = {**sub.integers, "port_mode": 0 if wave else 1}
            try:
                fmu = Fmu(path, sub.name, reals, integers, optional=("gamma", "port_mode"))
            except FmuError as exc:
                var = getattr(exc, "variable", None)         # a parameter/start/integer name the FMU lacks
                key = next((f"{k}.{var}" for k in ("parameters", "start", "integers") if var in getattr(sub, k)), "fmu")
                raise ConfigError(f"{scenario.source}: subsystems.{sub.name}.{key}: {exc}") from None
            if wave and "port_mode" not in fmu.variables:
                fmu.close()
                raise ConfigError(f"{scenario.source}: subsystems.{sub.name}.fmu: {path.name} has no wave port (integer parameter "
                                  f"port_mode); use a physical-domain master")
            if needs_rollback and not fmu.can_save_state:
                fmu.close()
                raise ConfigError(f"{scenario.source}: subsystems.{sub.name}.fmu: {path.name} cannot get and set its state, which "
                                  f"every master here needs to freeze and roll back")
            try:
                port = _port_spec(sub, fmu)
            except ConfigError as exc:
                fmu.close()
                raise ConfigError(f"{scenario.source}: {exc}") from None
            subsystems.append(Subsystem(sub.name, fmu, port, scenario.dt, wave=wave))
        for col, ref in scenario.outputs.items():
            name, var = ref.split(".")
            s = next(s for s in subsystems if s.name == name)
            if var not in s.fmu.variables:
                raise ConfigError(f"{scenario.source}: outputs.{col}: subsystem {name} has no variable {var!r}")
        sizes = [s.m for s in subsystems]
        E, F, offsets = coupling_structure(scenario, sizes)
        scene = Scene(scenario, subsystems, offsets, E, F, g, wave, gammas)
        if wave:
            scene.wave_map()
        return scene
    except BaseException:
        for s in subsystems:
            s.close()
        raise
