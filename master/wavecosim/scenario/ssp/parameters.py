"""Parameter bindings -> each component's `parameters` and `start` values.

SSP 1.0 (ParameterBinding): inline ssv:ParameterSet or an .ssv file given by source; the prefix is
prepended to every name; a system's names are hierarchical (element.variable); later bindings
win at one level and a higher level wins over a lower one; names matching no variable are
ignored (noted). Whether a value is a parameter or a start value is the variable's role in the
FMU's modelDescription: causality parameter -> parameters; an input, or a variable with initial
exact/approx -> start; anything else cannot be set and is an error."""
from ...errors import ConfigError
from .xmlfile import SSD, SSV, at, fail, number, parse, q

VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")


class Bindings:
    """Reads every binding once; `values(component, md)` gives its settings, `unused()` the names
    that reached no variable."""

    def __init__(self, flat, parameter_set=None):
        self.flat, self.chosen = flat, parameter_set
        self.files, self.used, self.seen = {}, set(), {}
        if parameter_set is not None:
            names = sorted({s.get("name") for s in self._all_sets()})
            if parameter_set not in names:
                raise_missing(flat, parameter_set, names)

    def _all_sets(self):
        for owner in self.flat.systems + [c.element for c in self.flat.components.values()]:
            for binding in _bindings(owner):
                yield from self._sets(binding)

    def _sets(self, binding):
        """The ssv:ParameterSet elements of one binding, inline or from its source file."""
        if binding.find(q(SSD, "ParameterMapping")) is not None:
            fail(self.flat.path, binding, "ssm:ParameterMapping is not supported")
        kind = binding.get("type", "application/x-ssp-parameter-set")
        if kind != "application/x-ssp-parameter-set":
            fail(self.flat.path, binding, f"parameter source type {kind!r} is not supported")
        source = binding.get("source")
        if source is None:
            values = binding.find(q(SSD, "ParameterValues"))
            return [] if values is None else values.findall(q(SSV, "ParameterSet"))
        if binding.get("sourceBase", "SSD") != "SSD":
            fail(self.flat.path, binding, "sourceBase='component' is not supported (give the .ssv beside the SSD)")
        path = (self.flat.path.parent / source).resolve()
        if not path.exists():
            fail(self.flat.path, binding, f"parameter file not found: {path}")
        if path not in self.files:
            self.files[path] = parse(path, "SystemStructureParameterValues.xsd")
        return [self.files[path]]

    def values(self, component, md):
        """{"parameters": {...}, "start": {...}} of one component and the bindings that gave them."""
        out, origins = {"parameters": {}, "start": {}}, []
        variables = {v.name: v for v in md.modelVariables}
        for owner, scope in component.scopes:
            for binding in _bindings(owner):
                prefix = binding.get("prefix", "")
                for pset in self._sets(binding):
                    if self.chosen is not None and pset.get("name") != self.chosen:
                        continue
                    path, hits = self.files_path(pset), 0
                    for param in pset.iter(q(SSV, "Parameter")):
                        self.seen.setdefault(id(param), (path, param))
                        name = prefix + param.get("name")
                        if not name.startswith(scope) or name[len(scope):] not in variables:
                            continue
                        self.used.add(id(param))
                        hits += 1
                        var = variables[name[len(scope):]]
                        role = _role(path, param, var)
                        out[role][var.name] = _value(path, param, var)
                    if hits:
                        origins.append(at(self.flat.path, binding)
                                       + (f" ({binding.get('source')})" if binding.get("source") else ""))
        return out, sorted(set(origins), key=origins.index)

    def files_path(self, pset):
        for path, root in self.files.items():
            if root is pset:
                return path
        return self.flat.path

    def unused(self):
        """'file line N: parameter X' for every bound name that reached no FMU variable."""
        return [f"{at(path, param)}: parameter {param.get('name')!r} matches no variable of "
                f"any component; ignored (SSP: unmatched names are ignored)"
                for key, (path, param) in self.seen.items() if key not in self.used]


def raise_missing(flat, chosen, names):
    raise ConfigError(f"{flat.path.name}: parameter set {chosen!r} not found (the file has: "
                      f"{', '.join(repr(n) for n in names) or 'none'})")


def _bindings(owner):
    holder = owner.find(q(SSD, "ParameterBindings"))
    return [] if holder is None else holder.findall(q(SSD, "ParameterBinding"))


def _role(path, param, var):
    """parameters or start, by the variable's causality, variability and initial."""
    if var.causality == "parameter":
        return "parameters"
    if var.variability != "constant" and (var.causality == "input" or var.initial in ("exact", "approx")):
        return "start"
    fail(path, param, f"{var.name} cannot be set before initialization (causality {var.causality}, "
                      f"variability {var.variability}, initial {var.initial})")


def _value(path, param, var):
    """The value of one ssv:Parameter as the Python value the scenario takes for its FMI type."""
    given = [child for child in param if child.tag in {q(SSV, t) for t in VALUE_TYPES}]
    if len(given) != 1:
        fail(path, param, f"needs one value element ({', '.join('ssv:' + t for t in VALUE_TYPES)})")
    el, kind = given[0], given[0].tag.split("}")[1]
    if kind == "Real":
        return number(path, el, "value", None)
    if kind == "Integer":
        return int(el.get("value"))
    if kind == "Boolean":
        return el.get("value") in ("true", "1")
    if kind == "String":
        return el.get("value")
    items = {item.name: int(item.value) for item in getattr(var.declaredType, "items", None) or []}
    if el.get("value") not in items:
        fail(path, el, f"{el.get('value')!r} is not an item of {var.name}'s enumeration "
                       f"(have: {', '.join(items) or 'none'})")
    return items[el.get("value")]
