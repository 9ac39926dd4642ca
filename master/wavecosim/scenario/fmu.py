"""One FMU as a scenario, run as fmpy's simulate runs it: its inputs at their start values, or driven
by a CSV file (the FMI cross-check format: a `time` column, one column per input, true/false for
Booleans, a time given twice for an event). The FMU is the one subsystem, named after its file;
the times come from its DefaultExperiment unless given. Reads files only; no FMU is instantiated."""
import csv
import re
from pathlib import Path

from fmpy import read_model_description

from ..errors import ConfigError, FmuError
from ..fmi.unpack import regular_file
from .config import input_file


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


def fmu_raw(path_given, input_csv=None, warn=None):
    """The scenario mapping of one FMU (and its input file): the subsystem, and a source table with
    one signal per column that names an input; columns naming no input, and inputs no column
    names (they keep their start values), are reported to `warn`."""
    path = regular_file(path_given, ConfigError)
    if path is None:
        raise FmuError(f"FMU file not found: {Path(path_given).resolve()}")
    name = component_name(path)
    raw = {"name": path.stem, "subsystems": {name: {"fmu": str(path)}}}
    if input_csv is None:
        return raw
    input_csv = input_file(input_csv, "--input")
    try:
        inputs = [v.name for v in read_model_description(str(path), validate=False).modelVariables
                  if v.causality == "input"]
    except Exception as exc:             # fmpy raises bare exceptions for bad archives
        raise FmuError(f"{path}: cannot read modelDescription.xml: {exc}") from None
    columns = _header(input_csv, "--input")[1:]
    source = "input" if name != "input" else "input_table"
    raw["sources"] = {source: {"csv": str(input_csv), "interpolation": "linear"}}
    raw["signals"] = [{"from": f"{source}.{c}", "to": f"{name}.{c}"} for c in columns if c in inputs]
    unused, unset = [c for c in columns if c not in inputs], [v for v in inputs if v not in columns]
    if warn and unused:
        warn(f"--input: {input_csv.name}: column(s) {', '.join(unused)} name no input of {path.name}; not used")
    if warn and unset:
        warn(f"--input: {input_csv.name} has no column for the input(s) {', '.join(unset)} of {path.name}; "
             f"they keep their start values")
    return raw


def load_fmu(path, input_csv=None, settings=None, warn=None):
    """The Scenario of one FMU (see fmu_raw), with `settings` (dt, T, start_time, ...) over the
    FMU's DefaultExperiment."""
    from .config import parse_scenario
    raw = fmu_raw(path, input_csv, warn)
    return parse_scenario(raw, str(Path(path)), Path(path).resolve().parent, settings)
