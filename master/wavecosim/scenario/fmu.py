"""One FMU as a scenario, run as fmpy's simulate runs it: its inputs at their start values, or driven
by a CSV file (the FMI cross-check format: a `time` column, one column per input, true/false for
Booleans, a time given twice for an event). The FMU is the one subsystem, named after its file;
the times come from its DefaultExperiment unless given. Reads files only; no FMU is instantiated."""
import csv
import difflib
import re
import zipfile
from dataclasses import replace
from pathlib import Path

from fmpy import read_model_description
from fmpy.simulation import _get_output_variables

from ..errors import ConfigError, FmuError
from ..fmi.unpack import regular_file
from .config import input_file
from .experiment import default_experiment, default_step


def is_fmu(path):
    """Whether `path` names an FMU file (.fmu)."""
    return path is not None and Path(path).suffix.lower() == ".fmu"


def component_name(path):
    """The subsystem name of a single FMU: its file name without .fmu, as a name (letters, digits, _ and -)."""
    name = re.sub(r"[^\w-]", "_", Path(path).stem)
    return name if re.match(r"[A-Za-z_]", name) else f"_{name}"


def _header(csv_path, where):
    try:
        with open(csv_path, newline="") as f:
            return [h.strip() for h in next(csv.reader(f, skipinitialspace=True), [])]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError(f"{where}: cannot read {csv_path}: {exc}") from None


def model_description(path):
    """fmpy's reading of the FMU file's modelDescription.xml; a file that is not an FMU (not a zip
    archive, a truncated one, no modelDescription.xml) is an FmuError naming it and what is wrong."""
    if not zipfile.is_zipfile(path):
        raise FmuError(f"{path}: not an FMU: not a zip archive (or a truncated one)")
    try:
        with zipfile.ZipFile(path) as z:
            z.getinfo("modelDescription.xml")
        return read_model_description(str(path), validate=False)
    except KeyError:
        raise FmuError(f"{path}: not an FMU: the archive has no modelDescription.xml") from None
    except Exception as exc:             # fmpy raises bare exceptions for bad archives and XML
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise FmuError(f"{path}: not an FMU: cannot read its modelDescription.xml: {first}") from None


def _recorded(name, description, warn):
    """The columns of an FMU without outputs: the variables fmpy's simulate records for it (its
    continuous states, else some of its other variables), said in a warning; None when it has outputs."""
    if any(v.causality == "output" for v in description.modelVariables):
        return None
    chosen = [v.name for v in _get_output_variables(description)]
    if warn:
        warn(f"{name}: the FMU has no outputs; recording {', '.join(chosen)} as fmpy does")
    return {f"{name}.{v}": f"{name}.{v}" for v in chosen}


def fmu_raw(path, input_csv=None, warn=None):
    """The scenario mapping of one FMU (and its input file): the subsystem, what fmpy records, and a
    source table with one signal per column; a column that names no input is a ConfigError naming
    the closest input; inputs no column names (they keep their start values) are reported to `warn`."""
    found = regular_file(path, ConfigError)
    if found is None:
        raise FmuError(f"FMU file not found: {Path(path).resolve()}")
    path = found
    description = model_description(path)
    name = component_name(path)
    raw = {"name": path.stem, "subsystems": {name: {"fmu": str(path)}}}
    outputs = _recorded(name, description, warn)
    if outputs:
        raw["outputs"] = outputs
    if input_csv is None:
        return raw
    input_csv = input_file(input_csv, "--input")
    inputs = [v.name for v in description.modelVariables if v.causality == "input"]
    columns = _header(input_csv, "--input")[1:]
    for column in columns:
        if column not in inputs:
            close = difflib.get_close_matches(column, inputs, n=1)
            hint = f"did you mean {close[0]}?" if close else f"have: {', '.join(inputs) or 'none'}"
            raise ConfigError(f"--input: {input_csv.name}: column {column!r} names no input of {path.name} ({hint})")
    source = "input" if name != "input" else "input_table"
    raw["sources"] = {source: {"csv": str(input_csv), "interpolation": "linear"}}
    raw["signals"] = [{"from": f"{source}.{c}", "to": f"{name}.{c}"} for c in columns]
    unset = [v for v in inputs if v not in columns]
    if warn and unset:
        warn(f"--input: {input_csv.name} has no column for the input(s) {', '.join(unset)} of {path.name}; "
             f"they keep their start values")
    return raw


def fmpy_times(path, settings):
    """The times fmpy's simulate takes for an FMU whose DefaultExperiment leaves them out, where the
    settings do too: stop time start + 1, the step by experiment.default_step; ({key: value}, notes)."""
    settings, given = settings or {}, default_experiment(path)
    start = settings.get("start_time")
    start = given.get("startTime", 0.0) if start is None else start
    out, notes = {}, []
    if settings.get("T") is None and "stopTime" not in given:
        out["T"] = start + 1.0
        notes.append(f"T = {out['T']:g} (fmpy's default: the start time + 1 s; --T chooses another)")
    stop = settings.get("T") if settings.get("T") is not None else given.get("stopTime", out.get("T"))
    if settings.get("dt") is None and "stepSize" not in given and stop > start:
        out["dt"], words = default_step(start, stop)
        notes.append(f"dt = {out['dt']:g} ({words})")
    return out, notes


def load_fmu(path, input_csv=None, settings=None, warn=None, changes=()):
    """The Scenario of one FMU (see fmu_raw), with `settings` (dt, T, start_time, ...) over the
    FMU's DefaultExperiment and `changes` ((key path, value), `--set`) set in its mapping."""
    from .config import parse_scenario
    from .overrides import apply_overrides
    later, changes = [], list(changes)           # the notes on the times come first
    raw = fmu_raw(path, input_csv, later.append)
    given = {**(settings or {}), **{k: v for k, v in changes if k in ("dt", "T", "start_time")}}
    times, notes = fmpy_times(path, given)
    for note in [f"{Path(path).name}: {note}" for note in notes] + later:
        (warn or (lambda text: None))(note)
    raw = apply_overrides({**raw, **times}, changes)
    scenario = parse_scenario(raw, str(Path(path)), Path(path).resolve().parent, settings)
    return replace(scenario, times_from={**scenario.times_from, **{k: "fmpy's default" for k in times}})
