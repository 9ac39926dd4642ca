"""The run's time grid when neither the command line, the overlay nor our annotation gives it.

Stop time: ssd:DefaultExperiment stopTime, else the FMUs' DefaultExperiment (the largest stopTime,
the scenario file's rule: scenario/experiment.py). Start time: ssd:DefaultExperiment startTime, else
the scenario file's rule. Step size, the first of: OSP `BaseStepSize` (OspSystemStructure.xml beside
the SSD), OMSimulator's fixed-step master (annotation org.openmodelica), the smallest `stepSize` of
the FMUs' DefaultExperiment, and last the interval fmpy's simulate_fmu takes for an FMU without one
(500 to 1000 steps over the run, a note says so). Without a stop time from anywhere, T (and so dt)
is asked for in one line."""
from types import SimpleNamespace

from ...errors import ConfigError
from ..experiment import default_step, from_fmus
from . import oms
from .osp import base_step_size
from .overlay import experiment
from .xmlfile import at

START_KEY = "start_time"


def _from_fmus(flat, key):
    """(value, origin) of `key` (dt or T) from the components' DefaultExperiments, or None."""
    subsystems = [SimpleNamespace(name=c.name, fmu_path=c.fmu, fmu=str(c.fmu)) for c in flat.components.values()]
    return from_fmus(subsystems, [key]).get(key)


def times(flat):
    """[(key, value, origin)] of the start and stop time the files give."""
    start, stop = experiment(flat.path, flat.root)
    out = [(START_KEY, start, "ssd:DefaultExperiment startTime")] if start is not None else []
    if stop is not None:
        return out + [("T", stop, "ssd:DefaultExperiment stopTime")]
    found = _from_fmus(flat, "T")
    return out + ([("T", *found)] if found else [])


def step(flat, raw):
    """(dt, origin, note or None) for a run whose settings give no dt."""
    value, path = base_step_size(flat.path.parent)
    if value is not None:
        return value, f"BaseStepSize of {path.name}", None
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
