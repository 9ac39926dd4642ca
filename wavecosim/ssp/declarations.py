"""Which connectors form power ports: an SSD does not say. Read, each over the one before it,
from OSP-IS `<fmu>_OspModelDescription.xml` beside the FMU (variable groups Force + LinearVelocity,
Torque + AngularVelocity, Voltage + Current), from our SSP annotation on the component
(type org.wavecosim.port), and from the overlay's `ports:` (README, "SSP in")."""
import yaml
from lxml import etree

from ..errors import ConfigError

from .xmlfile import SSC, SSD, WC, fail, q

PORT_ANNOTATION = "org.wavecosim.port"
LIST_KEYS = ("wave_in", "wave_out", "effort", "flow", "physical_in", "physical_out", "input", "sign")
OSP_PAIRS = {"Force": "LinearVelocity", "Torque": "AngularVelocity", "Voltage": "Current"}


def annotation(path, element, kind):
    """The one child element of an ssc:Annotation of type `kind` on `element`, or None."""
    holder = element.find(q(SSD, "Annotations"))
    for note in [] if holder is None else holder.findall(q(SSC, "Annotation")):
        if note.get("type") == kind:
            children = list(note)
            if len(children) != 1 or not children[0].tag.startswith(f"{{{WC}}}"):
                fail(path, note, f"an annotation of type {kind} holds one element of namespace {WC}")
            return children[0]
    return None


def attributes(element, list_keys=LIST_KEYS):
    """An element's attributes as scenario values: YAML scalars, whitespace lists for `list_keys`."""
    out = {}
    for key, text in element.attrib.items():
        values = [yaml.safe_load(v) for v in text.split()] if key in list_keys else [yaml.safe_load(text)]
        out[key] = values[0] if len(values) == 1 else values
    return out


def osp_port(component, md):
    """The port of an OSP-IS model description beside the FMU (every port group one channel per
    variable), {} when there is none; returns (port, file)."""
    folder, names = component.fmu.parent, {component.fmu.stem, md.modelName}
    for name in sorted(names):
        path = folder / f"{name}_OspModelDescription.xml"
        if path.exists():
            return _osp_channels(path, md), path
    return {}, None


def _osp_channels(path, md):
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{path.name} line {exc.lineno}: not well-formed XML: {exc.msg}") from None
    causality = {v.name: v.causality for v in md.modelVariables}
    port = {"physical_in": [], "physical_out": [], "input": []}
    for group in root.iter():
        kids = {etree.QName(k).localname: k for k in group if isinstance(k.tag, str)}
        for effort, flow in OSP_PAIRS.items():
            if effort in kids and flow in kids:
                _osp_pair(path, group, _refs(kids[effort]), _refs(kids[flow]), causality, port)
    return port if port["input"] else {}


def _refs(group):
    return [v for v in group.iter() if etree.QName(v).localname == "Variable"]


def _osp_pair(path, group, efforts, flows, causality, port):
    if len(efforts) != len(flows):
        fail(path, group, f"{len(efforts)} effort but {len(flows)} flow variables")
    for e, f in zip(efforts, flows):
        kinds = (causality.get(e.get("ref")), causality.get(f.get("ref")))
        if kinds not in (("input", "output"), ("output", "input")):
            fail(path, e, f"the FMU's {e.get('ref')!r} and {f.get('ref')!r} must be one input and one "
                          f"output, they are {kinds[0]} and {kinds[1]}")
        effort_in = kinds[0] == "input"
        port["physical_in"].append(e.get("ref") if effort_in else f.get("ref"))
        port["physical_out"].append(f.get("ref") if effort_in else e.get("ref"))
        port["input"].append("effort" if effort_in else "flow")


def declared_ports(path, components, mds, overlay_ports):
    """{subsystem: port dict} from OSP-IS, then our annotation, then the overlay, key by key;
    with where each came from ({subsystem: [origins]})."""
    ports, origins = {}, {}
    for key, comp in components.items():
        osp, osp_file = osp_port(comp, mds[key])
        note = annotation(path, comp.element, PORT_ANNOTATION)
        layers = [(osp, f"OSP-IS {osp_file.name}" if osp_file else None),
                  (attributes(note) if note is not None else {}, f"annotation {PORT_ANNOTATION} "
                   f"({path.name} line {note.sourceline})" if note is not None else None),
                  (overlay_ports.get(comp.name, {}), "the overlay (--ports)")]
        for layer, origin in layers:
            if layer:
                ports.setdefault(comp.name, {}).update(layer)
                origins.setdefault(comp.name, []).append(origin)
    return ports, origins
