"""The run's time grid when neither the command line, the overlay nor our annotation gives it.

Stop time: ssd:DefaultExperiment stopTime, else the largest stopTime of the FMUs' DefaultExperiment
(as for a scenario file). Start time: ssd:DefaultExperiment startTime. Step size, the
first of: OSP `BaseStepSize` (OspSystemStructure.xml beside the SSD), OMSimulator's fixed-step master
(annotation org.openmodelica), the smallest `stepSize` of the FMUs' DefaultExperiment, and last the
interval fmpy's simulate_fmu takes for an FMU without one (500 to 1000 steps over the run, a note
says so). Without a stop time from anywhere, T (and so dt) is asked for in one line."""
from fmpy.util import auto_interval

from ...errors import ConfigError
from . import oms
from .osp import base_step_size
from .overlay import experiment
from .xmlfile import at

START_KEY = "start_time"


def _fmu_experiments(flat, mds, field):
    """[(value, component name)] of one DefaultExperiment field over the FMUs that give it."""
    out = []
    for key, md in mds.items():
        exp = md.defaultExperiment
        text = getattr(exp, field, None) if exp is not None else None
        if text is not None and float(text) > 0:
            out.append((float(text), flat.components[key].name))
    return out


def times(flat, mds):
    """[(key, value, origin)] of the start and stop time the files give."""
    start, stop = experiment(flat.path, flat.root)
    out = []
    if start:
        out.append((START_KEY, start, "ssd:DefaultExperiment startTime"))
    if stop is not None:
        return out + [("T", stop, "ssd:DefaultExperiment stopTime")]
    given = _fmu_experiments(flat, mds, "stopTime")
    if given:
        value, name = max(given)
        out.append(("T", value, f"the largest DefaultExperiment stopTime of the FMUs ({name})"))
    return out


def step(flat, mds, raw):
    """(dt, origin, note or None) for a run whose settings give no dt."""
    value, path = base_step_size(flat.path.parent)
    if value is not None:
        return value, f"BaseStepSize of {path.name}", None
    value, element = oms.fixed_step(flat.path, flat.root)
    if value is not None:
        return value, f"OMSimulator's fixed-step master ({at(flat.path, element)})", None
    given = _fmu_experiments(flat, mds, "stepSize")
    if given:
        value, name = min(given)
        return value, f"the smallest DefaultExperiment stepSize of the FMUs ({name})", None
    if "T" not in raw:
        raise ConfigError(f"{flat.path}: T: neither the SSD nor its FMUs give a stop time or a step size; "
                          f"give --T and --dt (or dt and T in the overlay, --ports FILE)")
    duration = raw["T"] - raw.get(START_KEY, 0.0)
    value = float(auto_interval(duration))
    return value, "fmpy's interval for the run's length", (
        f"{flat.path.name}: dt: neither the SSD, OSP nor the FMUs give a step size; dt = {value:g} as fmpy's "
        f"simulate_fmu takes it for {duration:g} s (give --dt to choose)")
