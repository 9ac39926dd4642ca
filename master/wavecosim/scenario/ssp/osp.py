"""OSP-IS (the Open Simulation Platform's interface specification, read by libcosim) beside an SSP
system: `<fmu>_OspModelDescription.xml` next to an FMU names its power ports (variable groups
Force + LinearVelocity, Torque + AngularVelocity, Voltage + Current), and `OspSystemStructure.xml`
next to the SSD names power bonds between them, which are read as the two connections they stand for,
and its BaseStepSize, StartTime and StopTime the run's times. libcosim's own SSD files give the times
in an annotation (type com.opensimulationplatform, `osp:FixedStepAlgorithm baseStepSize startTime
stopTime`)."""
import math

from lxml import etree

from ...errors import ConfigError
from .bonds import Signal
from .xmlfile import SSC, at, fail, number, q

OSP_PAIRS = {"Force": "LinearVelocity", "Torque": "AngularVelocity", "Voltage": "Current"}
SYSTEM_FILE = "OspSystemStructure.xml"
SYSTEM_TIMES = {"BaseStepSize": "dt", "StartTime": "start_time", "StopTime": "T"}    # element -> scenario key
ANNOTATION = "com.opensimulationplatform"


def _read(path):
    try:
        return etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{path.name} line {exc.lineno}: not well-formed XML: {exc.msg}") from None


def _local(el):
    return etree.QName(el).localname if isinstance(el.tag, str) else ""


def model_description(component, md):
    """(port dict, {group name: [(effort, flow)]}, file) from the OSP-IS model description beside
    the FMU (every port group one channel per variable pair); ({}, {}, None) when there is none."""
    for name in sorted({component.fmu.stem, md.modelName}):
        path = component.fmu.parent / f"{name}_OspModelDescription.xml"
        if path.exists():
            port, groups = _ports(path, md)
            return port, groups, path
    return {}, {}, None


def _ports(path, md):
    causality = {v.name: v.causality for v in md.modelVariables}
    port, groups = {"physical_in": [], "physical_out": [], "input": []}, {}
    for group in _read(path).iter():
        kids = {_local(k): k for k in group}
        for effort, flow in OSP_PAIRS.items():
            if effort in kids and flow in kids:
                pairs = list(zip(_refs(kids[effort]), _refs(kids[flow])))
                if len(pairs) != len(_refs(kids[effort])) or len(pairs) != len(_refs(kids[flow])):
                    fail(path, group, "needs as many effort as flow variables")
                groups[group.get("name")] = [(e.get("ref"), f.get("ref")) for e, f in pairs]
                for e, f in pairs:
                    _channel(path, e, f, causality, port)
    return (port if port["input"] else {}), groups


def _refs(group):
    return [v for v in group.iter() if _local(v) == "Variable"]


def _channel(path, e, f, causality, port):
    kinds = (causality.get(e.get("ref")), causality.get(f.get("ref")))
    if kinds not in (("input", "output"), ("output", "input")):
        fail(path, e, f"the FMU's {e.get('ref')!r} and {f.get('ref')!r} must be one input and one output, "
                      f"they are {kinds[0]} and {kinds[1]}")
    effort_in = kinds[0] == "input"
    port["physical_in"].append(e.get("ref") if effort_in else f.get("ref"))
    port["physical_out"].append(f.get("ref") if effort_in else e.get("ref"))
    port["input"].append("effort" if effort_in else "flow")


def bond_connections(folder, groups, causality):
    """The connections the power bonds of OspSystemStructure.xml stand for, as Signals (factor 1):
    a VariableGroupConnection of two port groups joins their efforts and their flows, output to
    input; VariableConnections sharing a powerBond name are taken as they are."""
    path = folder / SYSTEM_FILE
    if not path.exists():
        return []
    out = []
    for el in _read(path).iter():
        ends = [(v.get("simulator"), v.get("name")) for v in el if _local(v) in ("VariableGroup", "Variable")]
        if _local(el) == "VariableGroupConnection" and len(ends) == 2 and all(e in groups for e in ends):
            out += _group_bond(path, el, ends, groups, causality)
        elif _local(el) == "VariableConnection" and el.get("powerBond") and len(ends) == 2:
            out.append(_directed(path, el, ends, causality))
    return out


def _group_bond(path, el, ends, groups, causality):
    (a, ga), (b, gb) = ends
    if len(groups[a, ga]) != len(groups[b, gb]):
        fail(path, el, f"port groups {ga!r} of {a} and {gb!r} of {b} have different sizes")
    out = []
    for (ea, fa), (eb, fb) in zip(groups[a, ga], groups[b, gb]):
        out += [_directed(path, el, [(a, ea), (b, eb)], causality), _directed(path, el, [(a, fa), (b, fb)], causality)]
    return out


def _directed(path, el, ends, causality):
    """A Signal from the output end to the input end of a connection given without direction."""
    kinds = [causality.get(end[0], {}).get(end[1]) for end in ends]
    if sorted(map(str, kinds)) != ["input", "output"]:
        fail(path, el, f"{'.'.join(ends[0])} and {'.'.join(ends[1])} must be an output and an input of two "
                       f"components, they are {kinds[0]} and {kinds[1]}")
    source, target = ends if kinds[0] == "output" else ends[::-1]
    return Signal(source, target, 1.0, 0.0, [el], path)


def system_times(folder):
    """{key: (value, origin)} of the times an OspSystemStructure.xml beside the SSD gives (dt from
    BaseStepSize, start_time from StartTime, T from StopTime; those it has), {} without one."""
    path = folder / SYSTEM_FILE
    if not path.exists():
        return {}
    out = {}
    for el in _read(path).iter():
        key = SYSTEM_TIMES.get(_local(el))
        if key is None or key in out:
            continue
        text = (el.text or "").strip()
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (key != "start_time" and value <= 0):
            fail(path, el, f"{_local(el)} must be a {'' if key == 'start_time' else 'positive '}number, got {text!r}")
        out[key] = (value, f"{_local(el)} of {path.name}")
    return out


def annotated_times(path, root):
    """{key: (value, origin)} of the first osp:FixedStepAlgorithm in the SSD's com.opensimulationplatform
    annotations, as libcosim reads it (dt from baseStepSize, start_time from startTime, T from
    stopTime; those it gives)."""
    for note in root.iter(q(SSC, "Annotation")):
        if note.get("type") != ANNOTATION:
            continue
        for el in note.iter():
            if _local(el) != "FixedStepAlgorithm":
                continue
            out = {}
            for attribute, key in (("baseStepSize", "dt"), ("startTime", "start_time"), ("stopTime", "T")):
                value = number(path, el, attribute, None)
                if value is not None and key == "dt" and value <= 0:
                    fail(path, el, f"baseStepSize must be a positive number, got {el.get(attribute)!r}")
                if value is not None:
                    out[key] = (value, f"SSD annotation osp:FixedStepAlgorithm {attribute} ({at(path, el)})")
            return out
    return {}
