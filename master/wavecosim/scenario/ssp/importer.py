"""An SSP system as a scenario mapping (the YAML format, README "The scenario file"): components
-> subsystems, parameter bindings -> parameters/start, connections -> signals, power bonds ->
couplings, outputs of the top system -> outputs. Reads files only; no FMU is instantiated."""
from dataclasses import dataclass, field
from pathlib import Path

from fmpy import read_model_description

from ...fmi.builtin import builtin_fmus
from ...errors import ConfigError
from . import structure
from .archive import locate_ssd
from .bonds import Signal, as_list, channels, couplings, find_bonds, where
from .osp import bond_connections
from .declarations import declared_ports
from .overlay import SETTINGS, annotated_settings, experiment_T, read_overlay
from .parameters import Bindings
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
    subsystems = _subsystems(flat, mds, fmus, Bindings(flat, parameter_set), out)
    _check_overlay_names(ports, overlay, subsystems)
    declared, origins, groups = declared_ports(ssd, flat.components, mds, overlay.get("ports", {}))
    signals = _with_osp_bonds(flat, _signals(flat, out.notes), groups, mds)
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
    if rest:
        out.raw["signals"] = [{"from": ".".join(s.source), "to": ".".join(s.target), "factor": s.factor,
                               "offset": s.offset} for s in rest]
        out.origins["signals"] = "the connections at " + ", ".join(where(ssd, s) for s in rest)
    outputs = overlay.get("outputs") or _outputs(flat, out)
    out.raw["outputs"] = outputs
    return out


def _descriptions(flat):
    """Each component's modelDescription and its `fmu` value (a built-in model's name for our own FMUs)."""
    mds, fmus = {}, {}
    for key, comp in flat.components.items():
        fmus[key] = str(comp.fmu)
        if builtin_fmus().get(comp.fmu.stem) == comp.fmu:
            fmus[key] = comp.fmu.stem
        try:
            mds[key] = read_model_description(str(comp.fmu), validate=False)
        except Exception as exc:               # fmpy raises bare exceptions for bad archives
            fail(flat.path, comp.element, f"cannot read the FMU's modelDescription.xml: {exc}")
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


def _subsystems(flat, mds, fmus, bindings, out):
    subsystems = {}
    for key, comp in flat.components.items():
        values, origins = bindings.values(comp, mds[key])
        subsystems[comp.name] = {"fmu": fmus[key], **{k: v for k, v in values.items() if v}}
        asked = comp.element.get("implementation", "any")
        out.origins[f"subsystems.{comp.name}"] = (
            f"component {comp.element.get('name')!r} ({at(flat.path, comp.element)}), {comp.fmu}"
            + ("" if asked in ("any", "CoSimulation") else f"; its {asked} implementation is asked for, its "
               "co-simulation interface runs"))
        if origins:
            out.origins[f"subsystems.{comp.name}.values"] = "parameter bindings: " + ", ".join(origins)
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


def _signals(flat, notes):
    """Every component input driven through the connections, as a Signal."""
    out = []
    for sink in flat.incoming:
        if sink[0] != "c":
            continue
        target = (flat.components[sink[1]].name, sink[2])
        found = structure.trace(flat, sink)
        if found is None:
            notes.append(f"{at(flat.path, flat.incoming[sink].element)}: {'.'.join(target)} is "
                         f"connected to a system connector that nothing drives; it keeps its start value")
            continue
        source, factor, offset, passed = found
        out.append(Signal((flat.components[source[1]].name, source[2]), target, factor, offset, passed))
    return out


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
    """name, description, T from the SSD, then our annotation, then the overlay, then the command line."""
    raw = {"name": flat.root.get("name", flat.path.stem), "description": flat.top.get("description", "")}
    T = experiment_T(flat.path, flat.root)
    if T is not None:
        raw["T"] = T
        out.origins["T"] = "ssd:DefaultExperiment stopTime"
    layers = [(annotated_settings(flat.path, flat.root), "annotation org.wavecosim.scenario"),
              ({k: overlay[k] for k in SETTINGS if k in overlay}, "the overlay (--ports)"),
              ({k: v for k, v in cli.items() if v is not None}, "the command line")]
    for layer, origin in layers:
        raw.update(layer)
        out.origins.update({key: origin for key in layer})
    if not raw["description"]:
        del raw["description"]
    return raw


def _outputs(flat, out):
    """{column: subsystem.variable} for every output connector of the top system."""
    outputs, top = {}, (flat.top.get("name"),)
    for name, el in structure.connectors(flat.top).items():
        found = structure.trace(flat, ("s", top, name)) if el.get("kind") == "output" else None
        if found is None:
            continue
        source, factor, offset, _ = found
        outputs[name] = f"{flat.components[source[1]].name}.{source[2]}"
        if (factor, offset) != (1.0, 0.0):
            out.notes.append(f"{at(flat.path, el)}: output {name} is recorded as {outputs[name]} "
                             f"without its transformation (factor {factor:g}, offset {offset:g})")
    out.origins["outputs"] = f"output connectors of system {flat.top.get('name')!r}"
    return outputs


def load_ssp(path, ports=None, parameter_set=None, settings=None):
    """(Scenario, Imported): the SSP system checked like a scenario file."""
    from ..config import parse_scenario
    imported = import_ssp(path, ports, parameter_set, settings)
    if not imported.raw["couplings"]:
        raise ConfigError(f"{imported.ssd}: couplings: no power bond found; declare which connectors form ports "
                          f"(an OSP-IS model description, the annotation org.wavecosim.port or --ports FILE; "
                          f"README, \"SSP in\")")
    for key in ("dt",):                   # gamma: auto where there is a power bond (config.py)
        if key not in imported.raw:
            raise ConfigError(f"{imported.ssd}: {key}: an SSD has none; give it in the overlay (--ports FILE) "
                              f"or on the command line (--{key})")
    return parse_scenario(imported.raw, str(imported.ssd), imported.ssd.parent), imported
