"""Parameter bindings -> each component's `parameters` and `start` values, and the values of
system connectors (SSP 1.0, ParameterBinding and ParameterMapping).

A binding is an inline ssv:ParameterSet or an .ssv file given by `source`; its `prefix` is prepended
to every name; its optional ssm:ParameterMapping (inline or an .ssm file) renames names (a source
name may feed several targets) and transforms values (ssc:LinearTransformation, and the Boolean,
Integer and Enumeration mapping tables); names it does not mention keep theirs. A system's names
are hierarchical (element.variable); later bindings win at one level and a higher level wins over a
lower one; names matching no variable are ignored (noted, one note per file). Whether a value is a
parameter or a start value is the variable's role in the FMU's modelDescription: causality
parameter -> parameters; an input, or a variable with initial exact/approx -> start; anything else
cannot be set and is an error."""
from dataclasses import dataclass

from .xmlfile import SSC, SSD, SSM, SSV, at, fail, number, parse, q

VALUE_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
SET_TYPE, MAPPING_TYPE = "application/x-ssp-parameter-set", "application/x-ssp-parameter-mapping"
NOTE_NAMES = 5                    # unmatched names listed in a note; the rest are counted


@dataclass
class Entry:
    """One value a binding gives: the name it reaches (prefix and mapping applied), the ssv:Parameter
    and its file, and the mapping entry that renamed or transforms it (None: taken as it is)."""
    name: str
    param: object
    path: object
    mapping: object = None
    mapping_path: object = None


class Bindings:
    """Reads every binding once; `values(component, md)` gives a component's settings,
    `connector_values(system key)` a system's connector values, `unused()` the notes for names that
    reached nothing."""

    def __init__(self, flat, parameter_set=None):
        self.flat, self.chosen = flat, parameter_set
        self.files, self.cache, self.used, self.seen = {}, {}, set(), {}
        if parameter_set is not None:
            names = sorted({s.get("name") for s in self._all_sets()})
            if parameter_set not in names:
                raise_missing(flat, parameter_set, names)

    def _all_sets(self):
        owners = self.flat.systems + [c.element for c in self.flat.components.values()]
        for owner in owners:
            for binding in _bindings(owner):
                yield from (pset for pset, _ in self._sets(binding))

    def _file(self, binding, attribute_owner, schema):
        """The root of the file `attribute_owner` names by `source`, resolved against the SSD."""
        if attribute_owner.get("sourceBase", "SSD") != "SSD":
            fail(self.flat.path, attribute_owner, "sourceBase='component' is not supported (give the file beside "
                                                  "the SSD)")
        path = (self.flat.path.parent / attribute_owner.get("source")).resolve()
        if not path.exists():
            fail(self.flat.path, attribute_owner, f"file not found: {path}")
        if path not in self.files:
            self.files[path] = parse(path, schema)
        return self.files[path], path

    def _sets(self, binding):
        """[(ssv:ParameterSet, its file)] of one binding, inline or from its source file."""
        kind = binding.get("type", SET_TYPE)
        if kind != SET_TYPE:
            fail(self.flat.path, binding, f"parameter source type {kind!r} is not supported")
        if binding.get("source") is None:
            values = binding.find(q(SSD, "ParameterValues"))
            return [] if values is None else [(s, self.flat.path) for s in values.findall(q(SSV, "ParameterSet"))]
        return [self._file(binding, binding, "SystemStructureParameterValues.xsd")]

    def _mapping(self, binding):
        """{source name: [(ssm:MappingEntry, its file)]} of a binding's ParameterMapping, or None."""
        holder = binding.find(q(SSD, "ParameterMapping"))
        if holder is None:
            return None
        if holder.get("type", MAPPING_TYPE) != MAPPING_TYPE:
            fail(self.flat.path, holder, f"parameter mapping type {holder.get('type')!r} is not supported")
        if holder.get("source") is not None:
            root, path = self._file(binding, holder, "SystemStructureParameterMapping.xsd")
        else:
            root, path = holder.find(q(SSM, "ParameterMapping")), self.flat.path
        mapping = {}
        for entry in [] if root is None else root.findall(q(SSM, "MappingEntry")):
            if entry.get("source") and entry.get("target"):        # an empty source maps nothing
                mapping.setdefault(entry.get("source"), []).append((entry, path))
        return mapping

    def _entries(self, binding):
        """Every value of one binding as Entries (read once per binding)."""
        if id(binding) not in self.cache:
            prefix, mapping, out = binding.get("prefix", ""), self._mapping(binding), []
            for pset, path in self._sets(binding):
                if self.chosen is not None and pset.get("name") != self.chosen:
                    continue
                for param in pset.iter(q(SSV, "Parameter")):
                    self.seen.setdefault(id(param), (path, param))
                    name = prefix + param.get("name")
                    targets = (mapping or {}).get(name) or [(None, None)]
                    out += [Entry(name if e is None else e.get("target"), param, path, e, p) for e, p in targets]
            self.cache[id(binding)] = (binding, out)
        return self.cache[id(binding)][1]

    def _bound(self, scopes, names):
        """{name: (Entry, binding)} for `names` over the scopes [(owner, prefix)] from the innermost
        outward (a higher level wins), and the bindings that gave them."""
        found, origins = {}, []
        for owner, scope in scopes:
            for binding in _bindings(owner):
                hits = 0
                for entry in self._entries(binding):
                    if entry.name.startswith(scope) and entry.name[len(scope):] in names:
                        self.used.add(id(entry.param))
                        found[entry.name[len(scope):]] = (entry, binding)
                        hits += 1
                if hits:
                    origins.append(at(self.flat.path, binding)
                                   + (f" ({binding.get('source')})" if binding.get("source") else ""))
        return found, sorted(set(origins), key=origins.index)

    def values(self, component, md):
        """{"parameters": {...}, "start": {...}} of one component and the bindings that gave them."""
        out = {"parameters": {}, "start": {}}
        variables = {v.name: v for v in md.modelVariables}
        found, origins = self._bound(component.scopes, variables)
        for name, (entry, _) in found.items():
            var = variables[name]
            out[role(entry.path, entry.param, var)][name] = transformed(entry, value(entry.path, entry.param, var), var)
        return out, origins

    def connector_values(self, key):
        """{connector: (value, Entry)} bound to the connectors of the system `key` (its own bindings
        and those above it): a value such a connector passes on to what it is connected to."""
        from .structure import connectors
        scopes = self.flat.system_scopes[key]
        found, _ = self._bound(scopes, connectors(scopes[0][0]))
        return {name: (transformed(entry, value(entry.path, entry.param, None), None), entry)
                for name, (entry, _) in found.items()}

    def unused(self):
        """One note per file for the bound names that reached no variable or connector."""
        by_file = {}
        for key, (path, param) in self.seen.items():
            if key not in self.used:
                by_file.setdefault(path, []).append(param)
        notes = []
        for path, params in by_file.items():
            names = ", ".join(repr(p.get("name")) for p in params[:NOTE_NAMES])
            more = f" and {len(params) - NOTE_NAMES} more" if len(params) > NOTE_NAMES else ""
            notes.append(f"{at(path, params[0])}: parameter{'s' if len(params) > 1 else ''} {names}{more} "
                         f"match{'es' if len(params) == 1 else ''} no variable of any component; ignored "
                         f"(SSP: unmatched names are ignored)")
        return notes


def raise_missing(flat, chosen, names):
    from ...errors import ConfigError
    raise ConfigError(f"{flat.path.name}: parameter set {chosen!r} not found (the file has: "
                      f"{', '.join(repr(n) for n in names) or 'none'})")


def _bindings(owner):
    holder = owner.find(q(SSD, "ParameterBindings"))
    return [] if holder is None else holder.findall(q(SSD, "ParameterBinding"))


def role(path, element, var):
    """parameters or start, by the variable's causality, variability and initial."""
    if var.causality == "parameter":
        return "parameters"
    if var.variability != "constant" and (var.causality == "input" or var.initial in ("exact", "approx")):
        return "start"
    fail(path, element, f"{var.name} cannot be set before initialization (causality {var.causality}, "
                        f"variability {var.variability}, initial {var.initial})")


def value(path, param, var):
    """The value of one ssv:Parameter as a Python value; an Enumeration item becomes its number
    when the variable `var` is known (None: a system connector's value, the item's name)."""
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
    if kind == "String" or var is None:
        return el.get("value")
    return item_number(path, el, el.get("value"), var)


def item_number(path, element, item, var):
    """An Enumeration item's number in `var`'s type (a number passes as it is)."""
    if not isinstance(item, str):
        return item
    items = {i.name: int(i.value) for i in getattr(var.declaredType, "items", None) or []}
    if item not in items:
        fail(path, element, f"{item!r} is not an item of {var.name}'s enumeration (have: {', '.join(items) or 'none'})")
    return items[item]


def transformed(entry, given, var):
    """A bound value through its mapping entry's transformation (ssc:LinearTransformation on numbers,
    a Boolean, Integer or Enumeration mapping table on those); as it is without one."""
    found = [c for c in (entry.mapping if entry.mapping is not None else ()) if c.tag.startswith(f"{{{SSC}}}")]
    if not found:
        return given
    el, kind = found[0], found[0].tag.split("}")[1]
    if kind == "LinearTransformation":
        if isinstance(given, bool) or not isinstance(given, (int, float)):
            fail(entry.mapping_path, el, f"a LinearTransformation needs a number, {entry.param.get('name')!r} is {given!r}")
        return number(entry.mapping_path, el, "factor", 1.0) * given + number(entry.mapping_path, el, "offset", 0.0)
    table = {_typed(kind, m.get("source")): _typed(kind, m.get("target")) for m in el.findall(q(SSC, "MapEntry"))}
    result = table.get(given, given)
    return item_number(entry.mapping_path, el, result, var) if kind == "EnumerationMappingTransformation" and var else result


def _typed(kind, text):
    if kind == "BooleanMappingTransformation":
        return text in ("true", "1")
    if kind == "IntegerMappingTransformation":
        return int(text)
    return text
