"""Unit conversion on a connection (SSP 1.0, Connection and ssc:Unit): a value passes from the unit
its start connector declares (`<ssc:Real unit="..."/>`) to the unit of its end connector when the
two differ, before the connection's LinearTransformation; both units must be defined in the SSD's
`ssd:Units` (SI exponents, factor, offset) and measure the same quantity, else the connection is
refused in one line. `suppressUnitConversion="true"` on the connection takes values as they are."""
from .xmlfile import SSC, SSD, fail, number, q

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration", "Binary")


def read_units(path, root) -> dict:
    """{name: (SI exponents, factor, offset)} of the units the SSD defines in ssd:Units."""
    holder = root.find(q(SSD, "Units"))
    units = {}
    for unit in [] if holder is None else holder.findall(q(SSC, "Unit")):
        base = unit.find(q(SSC, "BaseUnit"))
        exponents = tuple(int(base.get(b, "0")) for b in BASE) if base is not None else (0,) * len(BASE)
        scale = (number(path, base, "factor", 1.0), number(path, base, "offset", 0.0)) if base is not None else (1.0, 0.0)
        units[unit.get("name")] = (exponents, *scale)
    return units


def declared_unit(connector):
    """The unit a connector's type element declares (`<ssc:Real unit="N.m"/>`), or None."""
    for kind in TYPES:
        for ns in (SSC, SSD):
            typed = connector.find(q(ns, kind))
            if typed is not None:
                return typed.get("unit") or None
    return None


def conversion(path, conn, units, source, sink):
    """(a, b) with value in the sink's unit = a * value in the source's unit + b, for the
    connector elements at the two ends of `conn`; (1.0, 0.0) when nothing is to convert."""
    frm, to = declared_unit(source), declared_unit(sink)
    if frm is None or to is None or frm == to or conn.get("suppressUnitConversion") in ("true", "1"):
        return 1.0, 0.0
    missing = [u for u in (frm, to) if u not in units]
    if missing:
        fail(path, conn, f"connects unit {frm!r} to unit {to!r}, but ssd:Units does not define "
                         f"{' and '.join(repr(u) for u in missing)}; define it, or set suppressUnitConversion=\"true\"")
    (e_from, f_from, o_from), (e_to, f_to, o_to) = units[frm], units[to]
    if e_from != e_to:
        fail(path, conn, f"connects unit {frm!r} to unit {to!r}, which measure different quantities "
                         f"(SI exponents {_exponents(e_from)} and {_exponents(e_to)})")
    return f_from / f_to, (o_from - o_to) / f_to


def _exponents(exps):
    return " ".join(f"{b}^{e}" for b, e in zip(BASE, exps) if e) or "none"
