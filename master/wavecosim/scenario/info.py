"""What is inside an FMU, an SSP system or a scenario file (`wavecosim info`): an FMU's variables,
default experiment and capabilities; a system's components, connections and the power ports and
couplings the SSP import or the scenario declares. Reads files only; no FMU is instantiated."""
import zipfile
from pathlib import Path

from fmpy import read_model_description
from fmpy.model_description import ValidationError

from ..errors import ConfigError, FmuError
from ..fmi.builtin import builtin_fmus
from ..fmi.values import unit_of
from .fmu import is_fmu

CAPABILITIES = ("canGetAndSetFMUstate", "canSerializeFMUstate", "canHandleVariableCommunicationStepSize",
                "canInterpolateInputs", "maxOutputDerivativeOrder", "providesDirectionalDerivative",
                "canBeInstantiatedOnlyOncePerProcess", "needsExecutionTool")
FMI3_CAPABILITIES = ("fixedInternalStepSize", "providesIntermediateUpdate", "mightReturnEarlyFromDoStep",
                     "hasEventMode")
EXPERIMENT = ("startTime", "stopTime", "tolerance", "stepSize")
LISTED = ("parameter", "calculatedParameter", "structuralParameter", "input", "output", "independent")


def describe(path, ports=None, parameter_set=None) -> dict:
    """The description of `path`: an FMU (.fmu), an SSP system (.ssd, .ssp, folder, with an overlay
    `ports`), a scenario file (.yaml) or an example by its name; a ConfigError (FmuError for a broken
    FMU) in one line otherwise."""
    from ..examples import resolve
    from .ssp.archive import is_ssp
    path = Path(resolve(path))
    if not path.exists():
        raise ConfigError(f"{path}: no such file or folder")
    if is_fmu(path):
        return fmu_info(path)
    if is_ssp(path):
        return ssp_info(path, ports, parameter_set)
    if path.suffix.lower() in (".yaml", ".yml"):
        return scenario_info(path)
    raise ConfigError(f"{path}: not an FMU (.fmu), an SSP system (.ssd, .ssp, folder) or a scenario file (.yaml)")


def _model_description(path):
    """(modelDescription, note): read with validation, else without it and a note saying why."""
    if not zipfile.is_zipfile(path):
        raise FmuError(f"{path} is not an FMU (not a zip archive)")
    try:
        return read_model_description(str(path), validate=True), None
    except ValidationError as exc:
        first = exc.problems[0] if exc.problems else str(exc).splitlines()[0]
        note = f"modelDescription.xml does not conform to the FMI schema ({first}); read without validation"
    except Exception as exc:              # fmpy raises bare exceptions for bad archives
        raise FmuError(f"{path}: cannot read modelDescription.xml: {exc}") from None
    return read_model_description(str(path), validate=False), note


def _plain(value):
    """A number given as text in the modelDescription as a number; other values as they are."""
    if isinstance(value, str):
        try:
            return float(value) if any(c in value for c in ".eE") or value in ("inf", "-inf") else int(value)
        except ValueError:
            return value
    return value


def _variable(v):
    return {"name": v.name, "causality": v.causality, "variability": v.variability, "type": v.type,
            "unit": unit_of(v), "start": v.start, "description": v.description or ""}


def fmu_info(path) -> dict:
    """An FMU's identity, interfaces, default experiment, co-simulation capabilities and variables."""
    md, note = _model_description(path)
    cs, experiment = md.coSimulation, md.defaultExperiment
    wanted = CAPABILITIES + (FMI3_CAPABILITIES if md.fmiVersion.startswith("3") else ())
    interfaces = [name for name, kind in (("CoSimulation", cs), ("ModelExchange", md.modelExchange),
                                          ("ScheduledExecution", getattr(md, "scheduledExecution", None))) if kind]
    return {"kind": "FMU", "path": str(path), "fmi_version": md.fmiVersion, "model_name": md.modelName,
            "generation_tool": md.generationTool or "", "description": md.description or "",
            "interfaces": interfaces,
            "default_experiment": {k: _plain(getattr(experiment, k)) for k in EXPERIMENT
                                   if experiment is not None and getattr(experiment, k) is not None},
            "capabilities": {k: _plain(getattr(cs, k)) for k in wanted} if cs is not None else {},
            "variables": [_variable(v) for v in md.modelVariables], "notes": [note] if note else []}


def _component(name, fmu, fmu_path):
    """A component's FMU in brief: its file, version, tool, counts of inputs, outputs and parameters."""
    info = fmu_info(fmu_path)
    count = lambda kind: sum(v["causality"] == kind for v in info["variables"])      # noqa: E731
    return {"name": name, "fmu": fmu, "path": str(fmu_path), "fmi_version": info["fmi_version"],
            "notes": [f"{name}: {n}" for n in info["notes"]],
            "generation_tool": info["generation_tool"], "inputs": count("input"), "outputs": count("output"),
            "parameters": count("parameter"),
            "canGetAndSetFMUstate": bool(info["capabilities"].get("canGetAndSetFMUstate")),
            "default_experiment": info["default_experiment"]}


def _two_way(signals):
    """Pairs of components connected both ways (A's output into B and B's output into A): where an
    overlay's `ports:` could declare a power port (docs/your-fmus.md)."""
    ends = {}
    for s in signals:
        a, b = s["from"].split(".", 1)[0], s["to"].split(".", 1)[0]
        ends.setdefault((a, b), []).append(f"{s['from']} -> {s['to']}")
    return [{"components": [a, b], "connections": ends[(a, b)] + ends[(b, a)]}
            for a, b in sorted(ends) if a < b and (b, a) in ends]


def _system(name, source, times, subsystems, signals, couplings, notes):
    """The description of a system: its components (each FMU in brief), connections, ports and couplings."""
    components = [_component(n, s["fmu"], s["fmu_path"]) for n, s in subsystems.items()]
    return {"kind": "system", "path": str(source), "name": name, "experiment": times, "components": components,
            "connections": signals, "ports": {n: s["port"] for n, s in subsystems.items() if s.get("port")},
            "couplings": couplings, "two_way": _two_way(signals),
            "notes": notes + [n for c in components for n in c.pop("notes")]}


def ssp_info(path, ports=None, parameter_set=None) -> dict:
    """An SSP system as its import reads it (the ports and couplings it would make, with `ports` over it)."""
    from .ssp import import_ssp
    imported = import_ssp(path, ports, parameter_set)
    raw, folder = imported.raw, imported.ssd.parent
    subsystems = {n: {**s, "fmu_path": _fmu_path(s["fmu"], folder)} for n, s in raw["subsystems"].items()}
    times = {k: raw[k] for k in ("start_time", "T", "dt") if k in raw}
    return _system(raw.get("name", Path(path).stem), imported.ssd, times, subsystems, raw.get("signals", []),
                   raw.get("couplings", []), list(imported.notes))


def _fmu_path(fmu, folder):
    """The file of a scenario's `fmu` value: a built-in model's name or a path relative to `folder`."""
    if fmu.endswith(".fmu") or "/" in fmu:
        return (Path(folder) / fmu).resolve()
    built = builtin_fmus()
    if fmu not in built:
        raise ConfigError(f"{fmu}: no built-in FMU of this name (have: {', '.join(sorted(built))})")
    return built[fmu]


def scenario_info(path) -> dict:
    """A scenario file's system, as checked when it runs."""
    from .config import load_raw, load_scenario
    if "ports" in load_raw(path) and "subsystems" not in load_raw(path):
        raise ConfigError(f"{path}: a ports overlay of an SSP system, not a scenario: give it as --ports with "
                          "the system (wavecosim info System.ssd --ports FILE)")
    sc = load_scenario(path)
    subsystems = {s.name: {"fmu": s.fmu, "port": s.port, "fmu_path": s.fmu_path or _fmu_path(s.fmu, ".")}
                  for s in sc.subsystems}
    signals = [{"from": s.source, "to": s.target, "factor": s.factor, "offset": s.offset} for s in sc.signals]
    couplings = [{"type": c.type, "ports": list(c.ports)} for c in sc.couplings]
    return _system(sc.name, path, {"start_time": sc.start_time, "T": sc.T, "dt": sc.dt}, subsystems, signals,
                   couplings, [])


def _table(rows, fields, indent="  "):
    """Rows of dicts as aligned text lines under a header of `fields`."""
    cells = [[str(r.get(f, "")) if r.get(f) is not None else "" for f in fields] for r in rows]
    widths = [max(len(f), *(len(c[i]) for c in cells)) if cells else len(f) for i, f in enumerate(fields)]
    return [indent + "  ".join(v.ljust(w) for v, w in zip(line, widths)).rstrip()
            for line in [list(fields), *cells]]


def _short(value):
    return f"{value:g}" if isinstance(value, float) else str(value)


def _pairs(mapping):
    return ", ".join(f"{k} {v}" for k, v in mapping.items()) or "none given"


def text(info) -> list:
    """The description as plain text lines (`wavecosim info` without --json)."""
    body = _fmu_text(info) if info["kind"] == "FMU" else _system_text(info)
    return body + [f"note: {n}" for n in info["notes"]]


def _fmu_text(info):
    tool = f", by {info['generation_tool']}" if info["generation_tool"] else ""
    listed = [v for v in info["variables"] if v["causality"] in LISTED]
    hidden = len(info["variables"]) - len(listed)
    flags = [f"  {k}: {'yes' if v is True else 'no' if v is False else v}"
             for k, v in info["capabilities"].items() if v is not None]
    return [f"{info['path']}: FMI {info['fmi_version']} model {info['model_name']}{tool}; "
            f"{', '.join(info['interfaces']) or 'no interface'}",
            *([f"description: {info['description']}"] if info["description"] else []),
            f"default experiment: {_pairs(info['default_experiment'])}",
            "co-simulation capabilities:" + ("" if flags else " none (no co-simulation interface)"), *flags,
            f"variables: {len(info['variables'])}" + (f" ({hidden} local or other not listed; --json lists every "
                                                     "one)" if hidden else ""),
            *_table(sorted(listed, key=lambda v: LISTED.index(v["causality"])),
                    ("causality", "variability", "type", "name", "unit", "start", "description"))]


def _system_text(info):
    comps = [{**c, "FMI": c["fmi_version"], "state save": "yes" if c["canGetAndSetFMUstate"] else "no",
              "file": c["fmu"]} for c in info["components"]]
    links = [f"  {s['from']} -> {s['to']}" + ("" if (s.get("factor", 1), s.get("offset", 0)) == (1, 0) else
                                              f" (factor {s['factor']}, offset {s['offset']})")
             for s in info["connections"]]
    ports = [f"  {n}: " + ", ".join(f"{k} {' '.join(map(_short, v)) if isinstance(v, list) else _short(v)}"
                                    for k, v in p.items()) for n, p in info["ports"].items()]
    couplings = [f"  {c['type']}: {', '.join(map(str, c['ports']))}" for c in info["couplings"]]
    two_way = [f"  {' <-> '.join(w['components'])}: {', '.join(w['connections'])}" for w in info["two_way"]]
    return [f"{info['name']} ({info['path']}): {len(comps)} components, {len(links)} connections, "
            f"{len(couplings)} couplings",
            f"time: {_pairs(info['experiment'])}",
            f"components ({len(comps)}):",
            *_table(comps, ("name", "FMI", "inputs", "outputs", "parameters", "state save", "file")),
            f"connections ({len(links)}):", *links,
            f"power ports ({len(ports)}):", *(ports or ["  none declared (an overlay's `ports:` declares them, "
                                                         "--ports)"]),
            f"couplings ({len(couplings)}):", *couplings,
            *([f"connected both ways ({len(two_way)}; candidates for power ports):", *two_way] if two_way else [])]
