"""The system tree of an SSD, flattened: FMU components with their connectors, and every
connection traced through the connectors of nested systems to the component outputs that drive
it. Start and end of a connection do not give its direction; the connector kinds do (SSP 1.0,
Connection): a component or sub-system output and an input of the enclosing system are sources."""
import re
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlparse

from ...fmi.builtin import builtin_path
from .xmlfile import SSC, SSD, fail, number, q, start_line

FMU_TYPE = "application/x-fmu-sharedlibrary"


@dataclass
class Component:
    """One FMU component: its scenario name, resolved file, connectors {name: element} and the
    parameter scopes [(owner element, hierarchical prefix)] from the component outward."""
    name: str
    element: object
    fmu: Path
    connectors: dict
    scopes: list


@dataclass
class Link:
    """One connection into a sink: value(sink) = factor * value(source) + offset."""
    source: tuple
    factor: float
    offset: float
    element: object


@dataclass
class Flat:
    path: Path                                   # the .ssd file (messages, relative sources)
    root: object
    top: object = None                           # the top ssd:System
    components: dict = field(default_factory=dict)    # key (system path + name) -> Component
    incoming: dict = field(default_factory=dict)      # sink node -> Link
    systems: list = field(default_factory=list)       # every ssd:System, outermost first


def read(path, root) -> Flat:
    """Walk the SSD's systems; every connection becomes a Link into its sink node. A node is
    ("c", component key, variable) or ("s", system key, connector)."""
    flat = Flat(path=Path(path), root=root, top=root.find(q(SSD, "System")))
    _system(flat, flat.top, (), [])
    return flat


def connectors(el):
    """{name: ssd:Connector element} of a system or component."""
    return {c.get("name"): c for c in _children(el, "Connector")}


def _children(el, tag):
    holder = el.find(q(SSD, tag + "s"))
    return [] if holder is None else list(holder)


def _system(flat, sys_el, parent, scopes):
    key = parent + (sys_el.get("name"),)
    flat.systems.append(sys_el)
    kinds = {None: connectors(sys_el)}
    elements = {}
    for el in _children(sys_el, "Element"):
        name = el.get("name")
        if name in elements:
            fail(flat.path, el, f"a second element named {name!r} in system {sys_el.get('name')!r}")
        inner = [(owner, f"{name}.{prefix}") for owner, prefix in scopes] + [(sys_el, f"{name}.")]
        if el.tag == q(SSD, "System"):
            _system(flat, el, key, inner)
        elif el.tag == q(SSD, "Component"):
            _component(flat, el, key, inner)
        else:
            fail(flat.path, el, "only FMU components and systems are supported (no signal dictionaries)")
        elements[name] = (el, key + (name,))
        kinds[name] = connectors(el)
    for conn in _children(sys_el, "Connection"):
        _connection(flat, conn, key, elements, kinds)


def _component(flat, el, system_key, scopes):
    kind = el.get("type", FMU_TYPE)
    if kind != FMU_TYPE:
        fail(flat.path, el, f"component type {kind!r} is not supported (only {FMU_TYPE}: FMUs)")
    fmu = _source_path(flat, el)
    fmu = builtin_path(fmu) or fmu         # our own FMUs, named as .../build/fmus/<Id>.fmu
    if not fmu.exists():
        fail(flat.path, el, f"component file not found: {fmu}")
    name = _unique_name(flat, el.get("name"), system_key)
    flat.components[system_key + (el.get("name"),)] = Component(
        name=name, element=el, fmu=fmu, connectors=connectors(el), scopes=[(el, "")] + scopes[::-1])


def _source_path(flat, el) -> Path:
    """A component's source URI resolved against the SSD's folder (relative paths and file: URIs)."""
    uri = urlparse(el.get("source", ""))
    if uri.scheme not in ("", "file"):
        fail(flat.path, el, f"source {el.get('source')!r}: only relative paths and file: URIs are supported")
    return (flat.path.parent / unquote(uri.path)).resolve()


def _unique_name(flat, name, system_key):
    """The scenario name of a component: its own name (characters outside [A-Za-z0-9_-] become _),
    prefixed by its system's name when another component has it already."""
    clean = _identifier(name)
    taken = {c.name for c in flat.components.values()}
    while clean in taken:
        clean = f"{_identifier(system_key[-1])}_{clean}"
        system_key = system_key[:-1] or ("x",)
    return clean


def _identifier(name):
    clean = re.sub(r"[^\w-]", "_", name)
    return clean if re.match(r"[A-Za-z_]", clean) else f"_{clean}"


# (connector kind, on an element of the system?) -> role; the system's own connectors are seen from inside
ROLES = {("output", True): "source", ("input", True): "sink", ("output", False): "sink", ("input", False): "source"}


def _end(flat, conn, side, key, elements, kinds):
    """(node, role) of one end of a connection."""
    element, connector = conn.get(f"{side}Element"), conn.get(f"{side}Connector")
    if element is not None and element not in elements:
        fail(flat.path, conn, f"{side}Element {element!r} names no element of system {key[-1]!r} "
                              f"(have: {', '.join(elements) or 'none'})")
    declared = kinds[element]
    if connector not in declared:
        owner = f"element {element!r}" if element is not None else f"system {key[-1]!r}"
        fail(flat.path, conn, f"{owner} has no connector {connector!r} (have: {', '.join(declared) or 'none'})")
    kind = declared[connector].get("kind")
    if kind not in ("input", "output"):
        fail(flat.path, conn, f"connector {connector!r} is a {kind} connector; only input and output "
                              "connections are supported")
    if element is None:
        return ("s", key, connector), ROLES[kind, False]
    el, el_key = elements[element]
    return ("c" if el.tag == q(SSD, "Component") else "s", el_key, connector), ROLES[kind, True]


def _connection(flat, conn, key, elements, kinds):
    ends = [_end(flat, conn, side, key, elements, kinds) for side in ("start", "end")]
    roles = sorted(role for _, role in ends)
    if roles != ["sink", "source"]:
        fail(flat.path, conn, f"joins two {roles[0]}s: one end must deliver the value, the other take it")
    (source, _), (sink, _) = sorted(ends, key=lambda e: e[1] == "sink")
    factor, offset = _transformation(flat, conn)
    if sink in flat.incoming:
        first = start_line(flat.path, flat.incoming[sink].element)
        fail(flat.path, conn, f"{_label(sink)} is already driven by the connection on line {first}")
    flat.incoming[sink] = Link(source, factor, offset, conn)


def _transformation(flat, conn):
    """factor and offset of the connection's LinearTransformation (ssc:, also ssd: as fmpy writes it)."""
    for ns in (SSC, SSD):
        lt = conn.find(q(ns, "LinearTransformation"))
        if lt is not None:
            return number(flat.path, lt, "factor", 1.0), number(flat.path, lt, "offset", 0.0)
    for other in ("BooleanMappingTransformation", "IntegerMappingTransformation", "EnumerationMappingTransformation"):
        if conn.find(q(SSC, other)) is not None:
            fail(flat.path, conn, f"ssc:{other} is not supported (only ssc:LinearTransformation)")
    return 1.0, 0.0


def _label(node):
    return ".".join(node[1][1:] + (node[2],)) if node[1][1:] else node[2]


def trace(flat, sink):
    """The component output driving `sink` through any system connectors, with the composed
    factor and offset and the connections passed: (source node, factor, offset, [elements]), or
    None when a system connector on the way is driven by nothing."""
    factor, offset, node, passed = 1.0, 0.0, sink, []
    while node in flat.incoming:
        link = flat.incoming[node]
        factor, offset = factor * link.factor, factor * link.offset + offset
        passed.append(link.element)
        if link.source[0] == "c":
            return link.source, factor, offset, passed
        node = link.source
        if len(passed) > len(flat.incoming):
            fail(flat.path, link.element, "the connections through system connectors form a loop")
    return None
