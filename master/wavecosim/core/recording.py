"""What a run records: its output columns, each `column: SUBSYSTEM.variable`.

A scenario that names its columns (`outputs:` as a mapping) gets exactly those. Otherwise every
output and every input a signal drives, of every subsystem, in the scenario's order and each
FMU's order, is a column named `<subsystem>.<variable>` (as libcosim and OMSimulator name them).
Patterns (`outputs:` as a list, `--outputs`; shell-style globs) keep the columns whose name or
variable they match; a pattern without wildcards that names another variable adds it."""
import fnmatch

from ..errors import ConfigError, FmuError
from ..fmi.values import category

GLOB = set("*?[")


def output_columns(scenario, opened):
    """({column: "SUBSYSTEM.variable"}, notes) over the opened subsystems; every column is checked
    to be a scalar variable of a type wavecosim records (a one-line ConfigError otherwise)."""
    by_name = {s.name: s for s in opened}
    notes = []
    outputs = dict(scenario.outputs) if scenario.outputs else _everything(scenario, by_name, notes)
    if scenario.output_patterns:
        outputs = _narrow(scenario, outputs, by_name)
    for col, ref in outputs.items():
        _check(scenario, by_name, col, ref)
    for col in scenario.error:
        if col not in outputs:
            raise ConfigError(f"{scenario.source}: error: {col!r} is not an output column (have: "
                              f"{', '.join(list(outputs)[:8])}{', ...' if len(outputs) > 8 else ''})")
    return outputs, notes


def _order(scenario, by_name):
    """The subsystems in the order the scenario lists them."""
    listed = [n for n in scenario.order if n in by_name]
    return listed + [n for n in by_name if n not in listed]


def _everything(scenario, by_name, notes):
    """Every output and driven input of every subsystem, `<subsystem>.<variable>`; variables that
    cannot be recorded (arrays, clocks) are noted."""
    driven = {sig.target for sig in scenario.signals}
    outputs, skipped = {}, []
    for name in _order(scenario, by_name):
        for v in by_name[name].fmu.description.modelVariables:
            ref = f"{name}.{v.name}"
            if v.causality != "output" and ref not in driven:
                continue
            if getattr(v, "dimensions", None) or category(v.type) is None:
                skipped.append(f"{ref} ({'an array' if getattr(v, 'dimensions', None) else 'a ' + v.type})")
                continue
            outputs[ref] = ref
    if skipped:
        notes.append(f"{scenario.source}: outputs: not recorded, as only scalar values are: {', '.join(skipped)}")
    return outputs


def _narrow(scenario, outputs, by_name):
    """The columns some pattern matches (by column name or variable), then the variables named
    exactly by patterns that match no column."""
    def hit(pattern, col, ref):
        return fnmatch.fnmatchcase(col, pattern) or fnmatch.fnmatchcase(ref, pattern)
    kept = {c: r for c, r in outputs.items() if any(hit(p, c, r) for p in scenario.output_patterns)}
    for pattern in scenario.output_patterns:
        if any(hit(pattern, c, r) for c, r in outputs.items()):
            continue
        name, _, var = pattern.partition(".")
        if GLOB.isdisjoint(pattern) and name in by_name and var in by_name[name].fmu.variables:
            kept[pattern] = pattern
            continue
        example = next(iter(outputs), "SUBSYSTEM.variable")
        raise ConfigError(f"{scenario.source}: outputs: {pattern!r} matches no output and names no variable "
                          f"(columns are named like {example})")
    return kept


def _check(scenario, by_name, col, ref):
    name, var = ref.split(".", 1)
    where = f"{scenario.source}: outputs.{col}"
    if var not in by_name[name].fmu.variables:
        raise ConfigError(f"{where}: subsystem {name} has no variable {var!r}")
    try:
        by_name[name].fmu.kind(var)
    except FmuError as exc:
        raise ConfigError(f"{where}: {exc}") from None
