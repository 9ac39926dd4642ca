"""SSP files as XML: parse with lxml, validate against the SSP schemas fmpy ships, and name the file,
the element and its line in every error (one ConfigError line, exit code 2)."""
import math
import os
from copy import deepcopy
from pathlib import Path

from lxml import etree

from ...errors import ConfigError

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSM = "http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
WC = "urn:wavecosim:ssp:1"                 # our own annotations (README, "SSP in")
OSP = "http://opensimulationplatform.com/SSP/OSPAnnotations"     # libcosim's annotations
PREFIXES = {SSD: "ssd", SSC: "ssc", SSV: "ssv", SSM: "ssm", WC: "wc", OSP: "osp"}


def q(ns, tag):
    """The qualified name {ns}tag that lxml uses."""
    return f"{{{ns}}}{tag}"


def short(tag):
    """{ns}tag -> ssd:tag (the prefix the standard uses)."""
    if tag.startswith("{"):
        ns, local = tag[1:].split("}", 1)
        return f"{PREFIXES.get(ns, ns)}:{local}"
    return tag


def start_line(path, element):
    """The line where an element's start tag begins (lxml gives the line where it ends)."""
    local = etree.QName(element).localname
    token = f"<{element.prefix}:{local}" if element.prefix else f"<{local}"
    try:
        lines = Path(path).read_text(errors="replace").splitlines()
    except OSError:
        return element.sourceline
    for n in range(element.sourceline, max(element.sourceline - 30, 0), -1):
        if n <= len(lines) and token in lines[n - 1]:
            return n
    return element.sourceline


def at(path, element):
    """`file line N` of an element."""
    return f"{Path(path).name} line {start_line(path, element)}"


def where(path, element):
    """`file line N: <ssd:Connection name=...>`, the prefix of every error about one element."""
    attrs = " ".join(f"{k}={v!r}" for k, v in element.attrib.items()
                     if k in ("name", "startElement", "startConnector", "endElement", "endConnector", "source",
                              "factor", "offset", "type", "prefix"))
    return f"{at(path, element)}: <{short(element.tag)}{' ' + attrs if attrs else ''}>"


def fail(path, element, message):
    raise ConfigError(f"{where(path, element)}: {message}")


def parse(path, schema):
    """The root element of an SSP XML file, checked against fmpy's schema `schema` (e.g.
    SystemStructureDescription.xsd); a problem is one line with the file and its line."""
    try:
        tree = etree.parse(str(path))
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    except etree.XMLSyntaxError as exc:
        raise ConfigError(f"{Path(path).name} line {exc.lineno}: not well-formed XML: {exc.msg}") from None
    validate(path, tree.getroot(), schema)
    return tree.getroot()


def _schema(name):
    import fmpy
    return etree.XMLSchema(file=os.path.join(os.path.dirname(fmpy.__file__), "ssp", "schema", name))


def validate(path, root, schema):
    """Validate against the SSP 1.0 schema fmpy ships. SSP 2.0 files keep the 1.0 structure, so a
    copy with version 1.0 is checked; ssd:LinearTransformation (written for fmpy's reader) is
    checked as the standard's ssc:LinearTransformation."""
    copy = deepcopy(root)
    if copy.get("version", "").startswith("2."):
        copy.set("version", "1.0")
    for el in copy.iter(q(SSD, "LinearTransformation")):
        el.tag = q(SSC, "LinearTransformation")
    checker = _schema(schema)
    if not checker.validate(copy):
        err = checker.error_log[0]
        message = err.message
        for ns, prefix in PREFIXES.items():
            message = message.replace(f"{{{ns}}}", f"{prefix}:")
        raise ConfigError(f"{Path(path).name} line {err.line}: not a valid SSP file ({schema}): {message}")


def number(path, element, attribute, default):
    """A finite float attribute (factor, offset, a Real value); anything else fails naming it."""
    text = element.get(attribute)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        fail(path, element, f"{attribute} must be a finite number, got {text!r}")
    return value
