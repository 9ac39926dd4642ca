"""What a run of an SSP system records, the first that applies: the overlay's `outputs`, the signal
filter OMSimulator names on ssd:DefaultExperiment (columns `<component>.<variable>`, a comma in a name
as ';'), the output
connectors of the top system (column = connector name), else nothing here: the run records every
output and connected input of every component (the scenario's default)."""
from . import oms, structure
from .xmlfile import at

STRING_TYPES = ("String",)


def recorded(flat, mds, overlay, out):
    """{column: subsystem.variable}, or None for the scenario's default recording."""
    if overlay.get("outputs"):
        return overlay["outputs"]
    filter_path = oms.signal_filter(flat.path, flat.root)
    if filter_path is not None and not filter_path.exists():
        out.notes.append(f"{flat.path.name}: the signal filter {filter_path} is not there; recording without it")
    elif filter_path is not None:
        return _filtered(flat, mds, filter_path, out)
    return _top_outputs(flat, out) or None


def _top_outputs(flat, out):
    """{column: subsystem.variable} for every output connector of the top system."""
    outputs, top = {}, (flat.top.get("name"),)
    for name, el in structure.connectors(flat.top).items():
        if el.get("kind") != "output":
            continue
        node, factor, offset, _ = structure.trace(flat, ("s", top, name))
        if node[0] != "c":
            continue
        outputs[name] = structure.label(flat, node)
        if (factor, offset) != (1.0, 0.0):
            out.notes.append(f"{at(flat.path, el)}: output {name} is recorded as {outputs[name]} "
                             f"without its transformation (factor {factor:g}, offset {offset:g})")
    if outputs:
        out.origins["outputs"] = f"output connectors of system {flat.top.get('name')!r}"
    return outputs


def _paths(flat, mds):
    """{dotted path below the top system: (component key, its variables)} of every FMU component."""
    return {".".join(key[1:]): (key, {v.name: v for v in mds[key].modelVariables})
            for key in flat.components}


def _filtered(flat, mds, filter_path, out):
    """The variables of the signal filter, as columns named <component>.<variable>; a system
    connector is recorded as what drives it; what matches nothing, strings and undriven
    connectors are left out (one note)."""
    prefix = f"{flat.root.get('name')}.{flat.top.get('name')}."
    paths, outputs, left = _paths(flat, mds), {}, []
    for name in oms.filtered_names(filter_path, prefix):
        ref = _component_variable(paths, name, flat) or _system_connector(flat, name)
        if ref is None or ref[2] in STRING_TYPES:
            left.append(name)
            continue
        column = ref[0] if ref[1] is None else f"{flat.components[ref[1]].name}.{ref[0]}"
        outputs.setdefault(_column(column), ref[3])
    out.origins["outputs"] = f"the signal filter {filter_path.name}"
    if left:
        shown = ", ".join(left[:5]) + (f" and {len(left) - 5} more" if len(left) > 5 else "")
        out.notes.append(f"{filter_path.name}: not recorded (strings, or nothing drives them, or no such "
                         f"variable): {shown}")
    return outputs


def _column(name):
    """A variable's name as a column name: a comma (array elements such as table[1,1]) becomes ';',
    quotes and line breaks go (a named column holds none of them)."""
    return name.replace(",", ";").replace('"', "").replace("\n", " ").replace("\r", " ")


def _component_variable(paths, name, flat):
    """(variable, component key, type, subsystem.variable) for `name` = path.variable, or None."""
    for path, (key, variables) in paths.items():
        var = name[len(path) + 1:] if name.startswith(path + ".") else None
        if var in variables:
            return var, key, variables[var].type, f"{flat.components[key].name}.{var}"
    return None


def _system_connector(flat, name):
    """(column, None, type, subsystem.variable) of a system connector driven by a component output."""
    for key in flat.system_scopes:
        below = ".".join(key[1:])
        connector = name[len(below) + 1:] if below and name.startswith(below + ".") else name if not below else None
        if connector in structure.connectors(flat.system_scopes[key][0][0]):
            node, _, _, _ = structure.trace(flat, ("s", key, connector))
            if node[0] == "c":
                return name, None, "Real", structure.label(flat, node)
    return None
