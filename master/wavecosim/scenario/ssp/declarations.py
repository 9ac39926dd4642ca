"""Which connectors form power ports: an SSD does not say. Read, each over the one before it,
from OSP-IS `<fmu>_OspModelDescription.xml` beside the FMU (variable groups Force + LinearVelocity,
Torque + AngularVelocity, Voltage + Current), from our SSP annotation on the component
(type org.wavecosim.port), and from the overlay's `ports:` (README, "SSP in")."""
import yaml

from .osp import model_description
from .xmlfile import SSC, SSD, WC, at, fail, q

PORT_ANNOTATION = "org.wavecosim.port"
LIST_KEYS = ("wave_in", "wave_out", "effort", "flow", "physical_in", "physical_out", "input", "sign")


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
        values = [_scalar(v) for v in text.split()] if key in list_keys else [_scalar(text)]
        out[key] = values[0] if len(values) == 1 else values
    return out


def _scalar(text):
    """A YAML scalar (0.4, true, null, auto); any other text stays the string it is."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError:
        return text
    return text if isinstance(value, (dict, list)) else value


def declared_ports(path, components, mds, overlay_ports):
    """{subsystem: port dict} from OSP-IS, then our annotation, then the overlay, key by key;
    with where each came from ({subsystem: [origins]}) and the OSP-IS port groups
    ({(subsystem, group): [(effort, flow)]})."""
    ports, origins, groups = {}, {}, {}
    for key, comp in components.items():
        osp, found, osp_file = model_description(comp, mds[key])
        groups.update({(comp.name, g): pairs for g, pairs in found.items()})
        note = annotation(path, comp.element, PORT_ANNOTATION)
        layers = [(osp, f"OSP-IS {osp_file.name}" if osp_file else None),
                  (attributes(note) if note is not None else {}, f"annotation {PORT_ANNOTATION} "
                   f"({at(path, note)})" if note is not None else None),
                  (overlay_ports.get(comp.name, {}), "the overlay (--ports)")]
        for layer, origin in layers:
            if layer:
                ports.setdefault(comp.name, {}).update(layer)
                origins.setdefault(comp.name, []).append(origin)
    return ports, origins, groups
