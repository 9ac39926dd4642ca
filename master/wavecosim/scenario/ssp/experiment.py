"""The run's time grid when neither the command line, the overlay nor our annotation gives it.

Start and stop time, the first of: ssd:DefaultExperiment startTime / stopTime, the SSD's OSP
annotation (`osp:FixedStepAlgorithm startTime / stopTime`), OSP-IS `StartTime` / `StopTime`
(OspSystemStructure.xml beside the SSD), and the FMUs' DefaultExperiment (the scenario file's
rule: scenario/experiment.py). Step size, the first of: the OSP annotation's `baseStepSize`, OSP-IS
`BaseStepSize`, OMSimulator's fixed-step master (annotation org.openmodelica), the smallest
`stepSize` of the FMUs' DefaultExperiment, and last the interval fmpy's simulate_fmu takes for an
FMU without one (500 to 1000 steps over the run, a note says so). Without a stop time from
anywhere, T (and so dt) is asked for in one line. Each value's origin is kept (the run reports it)."""
from types import SimpleNamespace

from ...errors import ConfigError
from ..experiment import default_step, from_fmus
from . import oms
from .osp import annotated_times, system_times
from .overlay import experiment
from .xmlfile import at

START_KEY = "start_time"


def _from_fmus(flat, key):
    """(value, origin) of `key` (dt or T) from the components' DefaultExperiments, or None."""
    subsystems = [SimpleNamespace(name=c.name, fmu_path=c.fmu, fmu=str(c.fmu)) for c in flat.components.values()]
    return from_fmus(subsystems, [key]).get(key)


def _file_times(flat):
    """{key: (value, origin)} of the OSP annotation over OSP-IS (the SSD's own DefaultExperiment aside)."""
    return {**system_times(flat.path.parent), **annotated_times(flat.path, flat.root)}


def times(flat):
    """[(key, value, origin)] of the start and stop time the files give."""
    start, stop = experiment(flat.path, flat.root)
    osp = _file_times(flat)
    out = [(START_KEY, start, "ssd:DefaultExperiment startTime")] if start is not None else (
        [(START_KEY, *osp[START_KEY])] if START_KEY in osp else [])
    if stop is not None:
        return out + [("T", stop, "ssd:DefaultExperiment stopTime")]
    found = osp.get("T") or _from_fmus(flat, "T")
    return out + ([("T", *found)] if found else [])


def step(flat, raw):
    """(dt, origin, note or None) for a run whose settings give no dt."""
    osp = _file_times(flat)
    if "dt" in osp:
        return (*osp["dt"], None)
    value, element = oms.fixed_step(flat.path, flat.root)
    if value is not None:
        return value, f"OMSimulator's fixed-step master ({at(flat.path, element)})", None
    found = _from_fmus(flat, "dt")
    if found:
        return (*found, None)
    if "T" not in raw:
        raise ConfigError(f"{flat.path}: T: neither the SSD nor its FMUs give a stop time or a step size; "
                          f"give --T and --dt (or dt and T in the overlay, --ports FILE)")
    value, words = default_step(raw.get(START_KEY) or 0.0, raw["T"])
    return value, "fmpy's default step", f"{flat.path.name}: dt = {value:g} ({words})"
