"""Where each connected component input or parameter gets its value, traced through the connectors
of nested systems: from an element's output (a signal, held over each macro-step; a table column is
a source), or from a system connector that nothing drives but a parameter binding gives a value (an
input or parameter connector of a system: the value, through the connections' transformations,
becomes the component's start value or parameter and wins over the component's own binding, as in
OMSimulator). A connector nothing drives and nothing binds leaves the variable at its start value."""
from . import structure
from .bonds import Signal
from .parameters import item_number, role
from .xmlfile import at, fail


def wire(flat, mds, bindings, notes):
    """(the Signals into component inputs, {component key: ({"parameters"|"start": {var: value}},
    [origins])} from system connectors)."""
    signals, values = [], {}
    bound = {key: bindings.connector_values(key) for key in flat.system_scopes}
    for sink in flat.incoming:
        if sink[0] != "c":
            continue
        comp = flat.components[sink[1]]
        var = {v.name: v for v in mds[sink[1]].modelVariables}[sink[2]]
        node, factor, offset, passed = structure.trace(flat, sink)
        if node[0] != "s":
            if var.causality == "parameter":
                fail(flat.path, passed[0], f"{comp.name}.{var.name} is a parameter, set before the run, but "
                                           f"{structure.label(flat, node)} gives values during it")
            owner = (flat.components if node[0] == "c" else flat.tables)[node[1]]
            signals.append(Signal((owner.name, node[2]), (comp.name, var.name), factor, offset, passed))
            continue
        if node[2] not in bound[node[1]]:
            notes.append(f"{at(flat.path, flat.incoming[sink].element)}: {comp.name}.{var.name} is connected to "
                         f"a system connector that nothing drives; it keeps its start value")
            continue
        given, entry = bound[node[1]][node[2]]
        got, origins = values.setdefault(sink[1], ({"parameters": {}, "start": {}}, []))
        got[role(flat.path, passed[0], var)][var.name] = _through(flat, passed[0], given, factor, offset, var)
        origins.append(f"system connector {structure.label(flat, node)} ({at(entry.path, entry.param)})")
    return signals, values


def _through(flat, element, given, factor, offset, var):
    """A bound value passed through the connections' composed factor and offset."""
    given = item_number(flat.path, element, given, var) if var.type == "Enumeration" else given
    if (factor, offset) == (1.0, 0.0):
        return given
    if isinstance(given, bool) or not isinstance(given, (int, float)):
        fail(flat.path, element, f"the value {given!r} for {var.name} cannot pass a transformation "
                                 f"(factor {factor:g}, offset {offset:g})")
    return factor * given + offset
