"""The system tree of an SSD, flattened: FMU components and time tables with their connectors, and
every connection traced through the connectors of nested systems to the element output that drives
it. Start and end of a connection do not give its direction; the connector kinds do (SSP 1.0,
Connection): an output (or calculated parameter) of an element and an input (or parameter) of the
enclosing system are sources. A connection to the system itself names no element, or the element
"" (as OMSimulator writes it). Each connection converts between the units of its two connectors
(units.py), then applies its LinearTransformation."""
import csv
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import unquote, urlparse

from fmpy import read_model_description

from ...errors import ConfigError
from ...fmi.builtin import builtin_path
from ...fmi.unpack import regular_file
from .units import conversion, read_units
from .xmlfile import SSC, SSD, fail, number, q, start_line, where

FMU_TYPE = "application/x-fmu-sharedlibrary"
TABLE_TYPE = "application/table"          # a CSV time table as a component (OMSimulator's lookup table)
SOURCE_KINDS, SINK_KINDS = ("output", "calculatedParameter"), ("input", "parameter")


@dataclass
class Component:
    """One FMU component: its scenario name, resolved file, connectors {name: element}, the parameter
    scopes [(owner element, hierarchical prefix)] from the component outward and its modelDescription.
    A component that declares no connectors has its FMU's inputs, outputs and parameters as connectors."""
    name: str
    element: object
    fmu: Path
    connectors: dict
    scopes: list
    md: object = None


@dataclass
class Table:
    """A CSV time table (type application/table): its scenario name, file and output connectors
    {name: element}; without declared connectors every column is one."""
    name: str
    element: object
    csv: Path
    connectors: dict


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
    tables: dict = field(default_factory=dict)        # key (system path + name) -> Table
    units: dict = field(default_factory=dict)         # the ssd:Units definitions (units.read_units)
    incoming: dict = field(default_factory=dict)      # sink node -> Link
    systems: list = field(default_factory=list)       # every ssd:System, outermost first
    system_scopes: dict = field(default_factory=dict)  # system key -> its parameter scopes, as Component's


def read(path, root) -> Flat:
    """Walk the SSD's systems; every connection becomes a Link into its sink node. A node is
    ("c", component key, variable), ("t", table key, column) or ("s", system key, connector)."""
    flat = Flat(path=Path(path), root=root, top=root.find(q(SSD, "System")), units=read_units(path, root))
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
    flat.system_scopes[key] = [(sys_el, "")] + scopes[::-1]
    kinds = {None: connectors(sys_el)}
    elements = {}
    for el in _children(sys_el, "Element"):
        name = el.get("name")
        if name in elements:
            fail(flat.path, el, f"a second element named {name!r} in system {sys_el.get('name')!r}")
        inner = [(owner, f"{name}.{prefix}") for owner, prefix in scopes] + [(sys_el, f"{name}.")]
        kinds[name] = connectors(el)
        if el.tag == q(SSD, "System"):
            _system(flat, el, key, inner)
        elif el.tag == q(SSD, "Component"):
            kinds[name] = _component(flat, el, key, inner)
        else:
            fail(flat.path, el, "only components and systems are supported (no signal dictionaries)")
        elements[name] = (el, key + (name,))
    for conn in _children(sys_el, "Connection"):
        _connection(flat, conn, key, elements, kinds)


def _component(flat, el, system_key, scopes):
    """Read one FMU component or time table; its connectors {name: element}."""
    kind = el.get("type", FMU_TYPE)
    if kind not in (FMU_TYPE, TABLE_TYPE):
        fail(flat.path, el, f"component type {kind!r} is not supported (only {FMU_TYPE}: FMUs, and "
                            f"{TABLE_TYPE}: CSV time tables)")
    source = _source_path(flat, el)
    source = builtin_path(source) or source         # our own FMUs, named as .../build/fmus/<Id>.fmu
    if not source.exists():
        fail(flat.path, el, f"component file not found: {source}")
    name, key = _unique_name(flat, el.get("name"), system_key), system_key + (el.get("name"),)
    if kind == TABLE_TYPE:
        flat.tables[key] = Table(name, el, source, connectors(el) or _columns(flat, el, source))
        return flat.tables[key].connectors
    try:
        md = read_model_description(str(source), validate=False)
    except Exception as exc:               # fmpy raises bare exceptions for bad archives
        fail(flat.path, el, f"cannot read the FMU's modelDescription.xml: {exc}")
    declared = connectors(el) or {v.name: _connector(v.name, v.causality) for v in md.modelVariables
                                  if v.causality in SOURCE_KINDS + SINK_KINDS}
    flat.components[key] = Component(name=name, element=el, fmu=source, connectors=declared,
                                     scopes=[(el, "")] + scopes[::-1], md=md)
    return declared


def _connector(name, kind):
    """An ssd:Connector element made for a connector the SSD does not declare."""
    from lxml import etree
    return etree.Element(q(SSD, "Connector"), name=name, kind=kind)


def _columns(flat, el, csv_path):
    """A table without declared connectors: one Real output per column of its CSV header but the first."""
    from lxml import etree
    if csv_path.suffix.lower() != ".csv":
        fail(flat.path, el, f"a table component reads CSV files, not {csv_path.name}")
    with open(csv_path, newline="") as f:
        header = next(csv.reader(f), [])
    out = {}
    for column in [h.strip().strip('"') for h in header[1:]]:
        out[column] = _connector(column, "output")
        etree.SubElement(out[column], q(SSC, "Real"))
    return out


def _source_path(flat, el) -> Path:
    """A component's source URI resolved against the SSD's folder (relative paths and file: URIs)."""
    uri = urlparse(el.get("source", ""))
    if uri.scheme not in ("", "file"):
        fail(flat.path, el, f"source {el.get('source')!r}: only relative paths and file: URIs are supported")
    given = flat.path.parent / unquote(uri.path)
    return regular_file(given, lambda message: ConfigError(f"{where(flat.path, el)}: {message}")) or \
        Path(os.path.abspath(given))


def _unique_name(flat, name, system_key):
    """The scenario name of a component: its own name (characters outside [A-Za-z0-9_-] become _),
    prefixed by its system's name when another component has it already."""
    clean = _identifier(name)
    taken = {c.name for c in (*flat.components.values(), *flat.tables.values())}
    while clean in taken:
        clean = f"{_identifier(system_key[-1])}_{clean}"
        system_key = system_key[:-1] or ("x",)
    return clean


def _identifier(name):
    clean = re.sub(r"[^\w-]", "_", name)
    return clean if re.match(r"[A-Za-z_]", clean) else f"_{clean}"


def _role(kind, on_element):
    """source or sink of a connector kind, on an element of the system or on the system itself
    (seen from inside, its inputs and parameters deliver values)."""
    return "source" if (kind in SOURCE_KINDS) == on_element else "sink"


def _end(flat, conn, side, key, elements, kinds):
    """(node, role, connector element) of one end of a connection."""
    element, connector = conn.get(f"{side}Element") or None, conn.get(f"{side}Connector")
    if element is not None and element not in elements:
        fail(flat.path, conn, f"{side}Element {element!r} names no element of system {key[-1]!r} "
                              f"(have: {', '.join(elements) or 'none'})")
    declared = kinds[element]
    if connector not in declared:
        owner = f"element {element!r}" if element is not None else f"system {key[-1]!r}"
        fail(flat.path, conn, f"{owner} has no connector {connector!r} (have: {', '.join(declared) or 'none'})")
    kind = declared[connector].get("kind")
    if kind not in SOURCE_KINDS + SINK_KINDS:
        fail(flat.path, conn, f"connector {connector!r} is a {kind} connector; only input, output, parameter "
                              "and calculatedParameter connections are supported")
    if element is None:
        return ("s", key, connector), _role(kind, False), declared[connector]
    el, el_key = elements[element]
    tag = "s" if el.tag == q(SSD, "System") else "t" if el_key in flat.tables else "c"
    return (tag, el_key, connector), _role(kind, True), declared[connector]


def _connection(flat, conn, key, elements, kinds):
    ends = [_end(flat, conn, side, key, elements, kinds) for side in ("start", "end")]
    roles = sorted(role for _, role, _ in ends)
    if roles != ["sink", "source"]:
        fail(flat.path, conn, f"joins two {roles[0]}s: one end must deliver the value, the other take it")
    (source, _, source_el), (sink, _, sink_el) = sorted(ends, key=lambda e: e[1] == "sink")
    factor, offset = _transformation(flat, conn)
    a, b = conversion(flat.path, conn, flat.units, source_el, sink_el)
    if (a, b) != (1.0, 0.0):                 # the unit conversion first, then the transformation
        factor, offset = factor * a, factor * b + offset
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
            fail(flat.path, conn, f"ssc:{other} is not supported on a connection (only ssc:LinearTransformation)")
    return 1.0, 0.0


def _label(node):
    return ".".join(node[1][1:] + (node[2],)) if node[1][1:] else node[2]


def trace(flat, sink):
    """What drives `sink` through any system connectors: (node, factor, offset, [connections
    passed]), the node an element's output ("c" or "t") or, when the chain ends at a system
    connector nothing drives, that connector (`sink` itself when nothing drives it)."""
    factor, offset, node, passed = 1.0, 0.0, sink, []
    while node in flat.incoming:
        link = flat.incoming[node]
        factor, offset = factor * link.factor, factor * link.offset + offset
        passed.append(link.element)
        node = link.source
        if node[0] != "s":
            break
        if len(passed) > len(flat.incoming):
            fail(flat.path, link.element, "the connections through system connectors form a loop")
    return node, factor, offset, passed


def label(flat, node):
    """A node as a user reads it: component.variable, table.column, or the path of a system connector."""
    if node[0] == "c":
        return f"{flat.components[node[1]].name}.{node[2]}"
    if node[0] == "t":
        return f"{flat.tables[node[1]].name}.{node[2]}"
    return _label(node)
