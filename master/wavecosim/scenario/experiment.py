"""The times of a run where the scenario leaves them out, from the FMUs' DefaultExperiment: the start
time (the one every FMU that gives one gives), the step size (the smallest stepSize) and the stop
time (the largest stopTime). Reads modelDescription.xml only; no FMU is instantiated."""
import functools
import math
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from fmpy.util import auto_interval

from ..fmi.builtin import builtin_fmus

KEYS = {"start_time": "startTime", "dt": "stepSize", "T": "stopTime"}     # scenario key -> attribute


@functools.lru_cache(maxsize=512)
def _read(path, stamp):
    """{attribute: float} of the DefaultExperiment of an FMU file or folder ({} when it has none or
    cannot be read: the FMU's own error comes when it is opened)."""
    try:
        if Path(path).is_dir():
            root = ET.parse(Path(path) / "modelDescription.xml").getroot()
        else:
            with zipfile.ZipFile(path) as z:
                root = ET.fromstring(z.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return {}
    found = root.find("DefaultExperiment")
    out = {}
    for name, text in ({} if found is None else found.attrib).items():
        try:
            value = float(text)
        except ValueError:
            continue
        if math.isfinite(value):
            out[name] = value
    return out


def default_experiment(path):
    """The DefaultExperiment of the FMU at `path` as {attribute: float} (startTime, stopTime,
    stepSize, tolerance; those it gives)."""
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return {}
    return _read(str(path.resolve()), (st.st_mtime_ns, st.st_size))


def _fmu_file(sub):
    """The FMU file of a subsystem: its path, or a built-in FMU's build (None when unknown)."""
    if sub.fmu_path is not None:
        return sub.fmu_path
    return builtin_fmus().get(sub.fmu)


def from_fmus(subsystems, missing):
    """For each scenario key in `missing` (start_time, dt, T), {key: (value, what it came from)}
    from the subsystems' DefaultExperiments; a key no FMU gives is left out; start times that
    differ give (None, the list of them)."""
    declared = {}
    for sub in subsystems:
        path = _fmu_file(sub)
        experiment = default_experiment(path) if path is not None else {}
        for key in missing:
            if KEYS[key] in experiment:
                declared.setdefault(key, []).append((experiment[KEYS[key]], sub.name))
    out = {}
    for key, values in declared.items():
        if key == "start_time" and len({v for v, _ in values}) > 1:
            out[key] = (None, ", ".join(f"{name}: {v:g}" for v, name in values))
            continue
        value, name = (min if key == "dt" else max)(values)
        out[key] = (value, f"the DefaultExperiment {KEYS[key]} of {name}")
    return out


def default_step(start, stop):
    """(dt, the words that say where it came from) where nothing gives a step size: the interval fmpy's
    simulate_fmu takes for an FMU without a DefaultExperiment stepSize (fmpy.util.auto_interval, a round
    number giving 500 to 1000 steps from start to stop)."""
    span = stop - start
    value = float(auto_interval(span))
    return value, f"fmpy's default for a run of {span:g} s: {round(span / value)} steps; --dt chooses another"
