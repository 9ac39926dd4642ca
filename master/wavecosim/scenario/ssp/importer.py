"""An SSP system as a scenario mapping (the YAML format, README "The scenario file"): components
-> subsystems, time tables -> sources, parameter bindings and values through system connectors ->
parameters/start, connections -> signals, power bonds -> couplings, what is recorded -> outputs,
the time grid from the files (experiment.py). Reads files only; no FMU is instantiated."""
from dataclasses import dataclass, field, replace
from pathlib import Path

from ...fmi.builtin import builtin_name
from ...errors import ConfigError
from . import experiment, structure
from .archive import locate_ssd
from .bonds import as_list, channels, couplings, find_bonds, where
from .osp import bond_connections
from .declarations import declared_ports
from .outputs import recorded
from .overlay import SETTINGS, annotated_settings, read_overlay
from .parameters import Bindings
from .wiring import wire
from .xmlfile import at, fail, parse


@dataclass
class Imported:
    """The scenario mapping, the .ssd it came from, notes for the user and, per key path, where
    each part came from (comments of the YAML draft)."""
    raw: dict
    ssd: Path
    notes: list = field(default_factory=list)
    origins: dict = field(default_factory=dict)


def import_ssp(path, ports=None, parameter_set=None, settings=None) -> Imported:
    """Read `path` (.ssd, .ssp or folder) with an optional overlay file `ports`, the parameter sets
    named `parameter_set` only, and `settings` (the command line's dt, T, gamma) over everything."""
    ssd = locate_ssd(path)
    flat = structure.read(ssd, parse(ssd, "SystemStructureDescription.xsd"))
    overlay = read_overlay(ports) if ports else {}
    out = Imported(raw={}, ssd=ssd)
    mds, fmus = _descriptions(flat)
    bindings = Bindings(flat, parameter_set)
    wired, values = wire(flat, mds, bindings, out.notes)
    subsystems = _subsystems(flat, mds, fmus, bindings, values, overlay.get("tolerance"), out)
    _check_overlay_names(ports, overlay, subsystems)
    declared, origins, groups = declared_ports(ssd, flat.components, mds, overlay.get("ports", {}))
    signals = _with_osp_bonds(flat, wired, groups, mds)
    halves, rest = find_bonds(ssd, declared, signals)
    coupled, signs = couplings(ssd, declared, halves, _fixed_signs(declared))
    if halves:
        out.origins["couplings"] = "power bonds: the connections at " + ", ".join(
            sorted({where(ssd, h[2]) for h in halves.values()}))
    for name, port in declared.items():
        subsystems[name]["port"] = _with_signs(name, port, signs, origins[name])
        out.origins[f"subsystems.{name}.port"] = "; ".join(origins[name])
    out.raw = _settings(flat, overlay, settings or {}, out)
    out.raw.update(subsystems=_ordered(subsystems, coupled), couplings=coupled)
    if flat.tables:
        out.raw["sources"] = {t.name: {"csv": str(t.csv), "interpolation": "linear"} for t in flat.tables.values()}
        out.origins["sources"] = "time tables: " + ", ".join(at(ssd, t.element) for t in flat.tables.values())
    if rest:
        out.raw["signals"] = [{"from": ".".join(s.source), "to": ".".join(s.target), "factor": s.factor,
                               "offset": s.offset} for s in rest]
        out.origins["signals"] = "the connections at " + ", ".join(where(ssd, s) for s in rest)
    outputs = recorded(flat, mds, overlay, out)
    if outputs is not None:
        out.raw["outputs"] = outputs
    return out


def _descriptions(flat):
    """Each component's modelDescription and its `fmu` value (a built-in model's name for our own FMUs)."""
    mds, fmus = {}, {}
    for key, comp in flat.components.items():
        fmus[key] = str(comp.fmu)
        if builtin_name(comp.fmu):
            fmus[key] = comp.fmu.stem
        mds[key] = comp.md
        _check_connectors(flat, comp, mds[key])
    return mds, fmus


def _check_connectors(flat, comp, md):
    """Every connector of a component is a variable of its FMU, of the same kind."""
    causality = {v.name: v.causality for v in md.modelVariables}
    for name, el in comp.connectors.items():
        if name not in causality:
            fail(flat.path, el, f"{comp.fmu.name} has no variable {name!r} (unknown connector)")
        kind = el.get("kind")
        if kind in ("input", "output") and causality[name] != kind:
            fail(flat.path, el, f"connector kind {kind}, but {name!r} of {comp.fmu.name} has causality "
                                f"{causality[name]}")


def _subsystems(flat, mds, fmus, bindings, values, tolerance, out):
    """{name: subsystem mapping}: its FMU, the overlay's tolerance, and its values from the bindings,
    those coming through system connectors (`values`, wire()) over them."""
    subsystems = {}
    for key, comp in flat.components.items():
        own, origins = bindings.values(comp, mds[key])
        through, more = values.get(key, ({}, []))
        for k, v in through.items():
            own[k].update(v)
        subsystems[comp.name] = {"fmu": fmus[key], **{k: v for k, v in own.items() if v}}
        if tolerance is not None:
            subsystems[comp.name]["tolerance"] = tolerance
            out.origins[f"subsystems.{comp.name}.tolerance"] = "the overlay (--ports)"
        asked = comp.element.get("implementation", "any")
        out.origins[f"subsystems.{comp.name}"] = (
            f"component {comp.element.get('name')!r} ({at(flat.path, comp.element)}), {comp.fmu}"
            + ("" if asked in ("any", "CoSimulation") else f"; its {asked} implementation is asked for, its "
               "co-simulation interface runs"))
        if origins or more:
            out.origins[f"subsystems.{comp.name}.values"] = ", ".join(
                (["parameter bindings: " + ", ".join(origins)] if origins else []) + more)
    out.notes.extend(bindings.unused())
    return subsystems


def _check_overlay_names(ports, overlay, subsystems):
    for name in overlay.get("ports", {}):
        if name not in subsystems:
            raise ConfigError(f"{ports}: ports.{name}: names no component of the SSD "
                              f"(have: {', '.join(subsystems)})")


def _ordered(subsystems, coupled):
    """Signal-only subsystems first (document order), then the ported ones in the order the couplings
    name them (effort-output side first): the order a scenario file would list them."""
    named = [p.split("[")[0] for c in coupled for p in c["ports"]]
    rank = {name: named.index(name) if name in named else len(named) for name in subsystems}
    keys = sorted(subsystems, key=lambda n: (("port" in subsystems[n]), rank[n]))
    return {name: subsystems[name] for name in keys}


def _with_osp_bonds(flat, signals, groups, mds):
    """The SSD's signals and those the power bonds of an OspSystemStructure.xml beside it stand for
    (one already in the SSD is kept once; two different sources for one input are an error)."""
    causality = {flat.components[key].name: {v.name: v.causality for v in md.modelVariables}
                 for key, md in mds.items()}
    by_target = {s.target: s for s in signals}
    for s in bond_connections(flat.path.parent, groups, causality):
        first = by_target.setdefault(s.target, s)
        if first.source != s.source:
            fail(s.file, s.elements[0], f"{'.'.join(s.target)} is driven by {'.'.join(first.source)} in "
                                        f"{where(flat.path, first)}")
    return list(by_target.values())


def _fixed_signs(ports):
    """Signs known before the bonds: +1 on our wave ports, the declared ones on physical ports."""
    fixed = {}
    for name, port in ports.items():
        given = [1] * len(channels(port)) if "physical_out" not in port else as_list(port.get("sign"))
        fixed.update({(name, j): float(s) for j, s in enumerate(given)})
    return fixed


def _with_signs(name, port, signs, origins):
    """A physical port with the signs the bonds fixed (all channels or none)."""
    port = dict(port)
    m = len(channels(port))
    if "physical_out" in port and "sign" not in port and all((name, j) in signs for j in range(m)):
        values = [int(signs[(name, j)]) for j in range(m)]
        port["sign"] = values[0] if m == 1 else values
        origins.append("sign from the factors of the bond's connections")
    return port


def _settings(flat, overlay, cli, out):
    """name, description, start and stop time from the files, then our annotation, then the overlay,
    then the command line; then dt from the files when none of them gave it (the scenario's defaults
    do the rest: without power bonds the explicit master, with them gamma auto)."""
    raw = {"name": flat.root.get("name", flat.path.stem), "description": flat.top.get("description", "")}
    for key, value, origin in experiment.times(flat):
        raw[key], out.origins[key] = value, origin
    layers = [(annotated_settings(flat.path, flat.root), "annotation org.wavecosim.scenario"),
              ({k: overlay[k] for k in SETTINGS if k in overlay}, "the overlay (--ports)"),
              ({k: v for k, v in cli.items() if v is not None}, "the command line")]
    for layer, origin in layers:
        raw.update(layer)
        out.origins.update({key: origin for key in layer})
    if "dt" not in raw:
        raw["dt"], out.origins["dt"], note = experiment.step(flat, raw)
        out.notes.extend([note] if note else [])
    if not raw["description"]:
        del raw["description"]
    return raw


def load_ssp(path, ports=None, parameter_set=None, settings=None, changes=()):
    """(Scenario, Imported): the SSP system checked like a scenario file, with `changes` ((key path,
    value), `--set`) set in its mapping first, and where its times came from."""
    from ..config import parse_scenario
    from ..overrides import apply_overrides
    imported = import_ssp(path, ports, parameter_set, settings)
    scenario = parse_scenario(apply_overrides(imported.raw, changes), str(imported.ssd), imported.ssd.parent)
    changed = {key.split(".")[-1] for key, _ in changes}
    times_from = {**scenario.times_from, **{k: v for k, v in imported.origins.items()
                                            if k in scenario.times_from and k not in changed}}
    return replace(scenario, times_from=times_from), imported
