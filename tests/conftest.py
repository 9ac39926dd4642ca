"""The shared FMU harness: the built FMUs, one FMU instance addressed by variable names (fmpy),
and the discrete-passivity and rollback checks every model family runs."""
import re

import numpy as np
import pytest
from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from wavecosim.fmi.builtin import build_all

from paths import ROOT
PASSIVITY_RTOL = 1e-12


@pytest.fixture(scope="session")
def built_fmus():
    """{identifier: Path} of every FMU built from models/ and specs/ by wavecosim/fmi/build.py."""
    return build_all()


def channels(folder, models=ROOT / "models"):
    """Port channels (wave_in, wave_out, effort, flow, physical_in, kind) from config.h."""
    text = (models / folder / "config.h").read_text()
    return re.findall(r"X\((\w+), (\w+), (\w+), (\w+), (\w+), (FLOW_INPUT|EFFORT_INPUT)\)", text)


class Instance:
    """One FMU instance addressed by variable names (fmpy's FMU2Slave), initialized with the given
    values; it keeps the messages the FMU logs. `fmus` maps identifier -> (fmu path, unzip dir)."""

    def __init__(self, fmus, ident, name="test", reals=None, ints=None):
        path, unzipped = fmus[ident]
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.reals = [v.name for v in md.modelVariables if v.type == "Real"]
        self.integers = {v.name for v in md.modelVariables if v.type == "Integer"}
        self.messages = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=self._callbacks)
        try:
            self.fmu.setupExperiment(startTime=0.0)
            self.fmu.enterInitializationMode()
            for k, v in (ints or {}).items():
                self.fmu.setInteger([self.vr[k]], [int(v)])
            self.set(**(reals or {}))
            self.fmu.exitInitializationMode()
        except Exception as exc:
            exc.fmu_messages = self.messages          # what the FMU logged before it refused
            raise
        self.t = 0.0

    def _log(self, env, name, status, category, message):
        self.messages.append(message.decode())

    def start(self, **values):
        """Reset, then initialize again at t = 0 with these start values and parameters."""
        self.fmu.reset()
        self.fmu.setupExperiment(startTime=0.0)
        for name, value in values.items():
            if name in self.integers:
                self.fmu.setInteger([self.vr[name]], [int(value)])
            else:
                self.fmu.setReal([self.vr[name]], [float(value)])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        self.t = 0.0
        return self

    def set(self, **values):
        if values:
            self.fmu.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names):
        return np.array(self.fmu.getReal([self.vr[k] for k in names]))

    def all_reals(self):
        return self.get(*self.reals)

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture(scope="session")
def extracted(built_fmus, tmp_path_factory):
    """{identifier: (fmu path, unzip dir)} of every built FMU."""
    return {ident: (path, extract(str(path), unzipdir=str(tmp_path_factory.mktemp(ident))))
            for ident, path in built_fmus.items()}


@pytest.fixture
def open_fmu(extracted):
    """open_fmu(ident) -> an Instance with default values, freed after the test."""
    opened = []

    def _open(ident):
        opened.append(Instance(extracted, ident))
        return opened[-1]

    yield _open
    for inst in opened:
        inst.free()


def random_instance(fmus, ident, rng, mode, damped, models):
    """An Instance at random states (scales from models[ident]) and gamma, damped or not."""
    folder, damper, states, _ = models[ident]
    reals = {k: s * rng.standard_normal() for k, s in states.items()}
    reals["gamma"] = 10.0 ** rng.uniform(-1.5, 1.5)
    ints = {"port_mode": mode}
    if ident == "HeavyChain":
        ints.update(n=int(rng.integers(1, 40)), newton_sweeps=1)
        reals["amplitude"] = rng.uniform(-0.6, 0.6)
    reals[damper] = rng.uniform(0.0, 2.0) if damped else 0.0
    return Instance(fmus, ident, reals=reals, ints=ints)


def check_discrete_passivity(new_instance, chans, phys_scale, mode, rng, instances=10):
    """Condition 2 over `instances` instances from new_instance(damped) x 10 random (input, gamma,
    h): equality when undamped, the wave closure in wave mode. Returns the worst residual."""
    worst = 0.0
    for trial in range(instances):
        damped = trial % 2 == 1
        inst = new_instance(damped)
        try:
            for _ in range(10):
                h = 10.0 ** rng.uniform(-3, -1)
                gamma = 10.0 ** rng.uniform(-1.5, 1.5)
                inst.set(gamma=gamma)
                H0 = inst.get("H")[0]
                if mode == 0:
                    a = rng.standard_normal(len(chans)) * np.sqrt(h * (abs(H0) + 1.0))
                    inst.set(**{c[0]: x for c, x in zip(chans, a)})
                else:
                    inst.set(**{c[4]: phys_scale * rng.standard_normal() for c in chans})
                inst.step(h)
                H1 = inst.get("H")[0]
                e = inst.get(*[c[2] for c in chans])
                f = inst.get(*[c[3] for c in chans])
                supply = h * float(e @ f)
                scale = abs(H0) + abs(H1) + abs(supply) + 1e-300
                resid = (H1 - H0 - supply) / scale
                assert resid <= PASSIVITY_RTOL, (mode, resid)
                if not damped:
                    assert abs(resid) <= PASSIVITY_RTOL, (mode, resid)
                worst = max(worst, abs(resid) if not damped else resid)
                if mode == 0:  # the step honours the wave closure, so supply = (|a|^2 - |b|^2)/2
                    b = inst.get(*[c[1] for c in chans])
                    target = np.sqrt(2.0 * gamma / h) * a
                    assert np.allclose(e + gamma * f, target, rtol=1e-11, atol=1e-11 * np.abs(target).max())
                    assert abs(0.5 * (a @ a - b @ b) - supply) <= 1e-11 * (a @ a + b @ b + 1e-300)
        finally:
            inst.free()
    return worst


def check_rollback(inst, chans, rng):
    """Step, save, step, restore (directly and via serialization), step: identical outputs."""
    h = 0.01
    for _ in range(3):
        inst.set(**{c[0]: 0.1 * rng.standard_normal() for c in chans})
        inst.step(h)
    inputs = {c[0]: 0.1 * rng.standard_normal() for c in chans}
    state = inst.fmu.getFMUState()
    blob = inst.fmu.serializeFMUState(state)
    restored = inst.fmu.deserializeFMUState(blob)
    runs = []
    for saved in (None, state, restored):
        if saved is not None:
            inst.fmu.setFMUState(saved)
            inst.t -= 2 * h
        inst.set(**inputs)
        inst.step(h)
        inst.step(h)
        runs.append(inst.get(*inst.reals).tobytes())
    inst.fmu.freeFMUState(state)
    inst.fmu.freeFMUState(restored)
    assert runs[0] == runs[1] == runs[2]


# FMI type -> the fmpy get/set method suffix that carries it (FMI 2 and FMI 3), for plain fmpy loops
FMPY_ACCESS = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean",
               "String": "String", "Float64": "Float64", "Float32": "Float32",
               **{f"{s}Int{b}": f"{s}Int{b}" for s in ("", "U") for b in (8, 16, 32, 64)}}


def fmpy_loop(path, dt, n_steps, names, start_time=None, tolerance=None, signals=None, unzipdir=None):
    """The reference of a single-FMU run: fmpy alone, as a plain loop. Set up as fmpy's simulate sets
    an FMU up (the DefaultExperiment's start time and tolerance unless given), the input `signals`
    (a structured array for fmpy's Input, or None) applied in initialization mode at t_0 and before
    every doStep(t_n, dt), t_n = t_0 + n dt; `names` read at t_0 and after each step (before the next
    inputs are applied). Returns
    {name: list of values} (Booleans as 0/1, Strings as text), one entry per grid point."""
    from fmpy import extract, instantiate_fmu, read_model_description
    from fmpy.simulation import Input
    md = read_model_description(str(path), validate=False)
    experiment = md.defaultExperiment
    if start_time is None:
        start_time = float(experiment.startTime) if experiment and experiment.startTime is not None else 0.0
    if tolerance is None and experiment and experiment.tolerance is not None:
        tolerance = float(experiment.tolerance)
    fmu = instantiate_fmu(extract(str(path), unzipdir=unzipdir), md, fmi_type="CoSimulation")
    variables = {v.name: v for v in md.modelVariables}
    inputs = Input(fmu, md, signals)
    if md.fmiVersion == "2.0":
        fmu.setupExperiment(tolerance=tolerance, startTime=start_time)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(tolerance=tolerance, startTime=start_time)
    inputs.apply(start_time)
    fmu.exitInitializationMode()

    def read():
        for name in names:
            v = variables[name]
            access = "Int64" if v.type == "Enumeration" and md.fmiVersion != "2.0" else FMPY_ACCESS[v.type]
            value = getattr(fmu, f"get{access}")([v.valueReference])[0]
            rows[name].append(value.decode() if isinstance(value, bytes) else
                              value if isinstance(value, str) else float(value))

    rows = {name: [] for name in names}
    inputs.apply(start_time, after_event=True)
    read()
    for n in range(n_steps):
        t = start_time + n * dt
        inputs.apply(t, after_event=True)
        if not _step_goes_on(fmu, t, dt):           # the FMU ended the simulation with this step
            read()
            break
        read()
    fmu.terminate()
    fmu.freeInstance()
    return rows


def _step_goes_on(fmu, t, dt):
    """doStep(t, dt); False when the FMU asks to end the simulation (fmpy's simulate then stops)."""
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import fmi2Terminated
    try:
        out = fmu.doStep(t, dt)
    except FMICallException as exc:
        if exc.status == 2 and fmu.getBooleanStatus(fmi2Terminated):
            return False
        raise
    return not (isinstance(out, tuple) and out[1])          # FMI 3: terminateSimulation


def same_bits(result, component, rows):
    """Whether every column component.name of a RunResult holds exactly the loop's values."""
    trajectory = result.trajectory
    for name, values in rows.items():
        got = trajectory[f"{component}.{name}"]
        if got.dtype.kind == "U":
            assert list(got) == values, name
        else:
            assert np.array_equal(got, np.array(values, float)), (name, got[:5], values[:5])
    return True


def input_signals(path):
    """A CSV input file as the structured array fmpy's Input takes (true/false columns as Booleans)."""
    import csv
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f, skipinitialspace=True) if r]
    header, data = [h.strip() for h in rows[0]], rows[1:]
    words = {"true": True, "false": False}
    columns = [[c.strip().lower() for c in col] for col in zip(*data)]
    kinds = [np.bool_ if all(c in words for c in col) else np.float64 for col in columns]
    out = np.empty(len(data), dtype=list(zip(header, kinds)))
    for name, kind, col in zip(header, kinds, columns):
        out[name] = [words[c] for c in col] if kind is np.bool_ else [float(c) for c in col]
    return out


@pytest.fixture(scope="session")
def faulty_scenario(built_fmus):
    """faulty_scenario(fault, step, T, **integers) -> the Table I scenario (a mapping) with B a FaultySide
    (models/faulty_side) that faults at macro-step `step` (the faults of its config.h: 1 segfault,
    2 exit(0), 3 endless loop, 4 abort(), 5..14 signal-blind hangs, stops, thread and fork crashes and
    faults outside doStep, 15 an error logged as a printf format with its arguments, 16 NaN outputs with
    status OK, 17 a broken restore from that step on, 18 _exit(3), 19 every file descriptor closed, then
    a segfault); integers such as log_bytes go to the FMU too."""
    import copy
    import yaml
    from wavecosim.scenario.config import DEFAULT_CONFIG
    base = yaml.safe_load(DEFAULT_CONFIG.read_text())

    def make(fault=0, step=-1, T=30.0, **integers):
        raw = copy.deepcopy(base)
        raw["T"] = T
        raw["subsystems"]["B"].update(fmu="FaultySide", parameters={}, start={"v": 0.0},
                                      integers={"fault": fault, "fault_step": step, **integers})
        raw["outputs"].update(q2="B.x", v2="B.v")
        return raw
    return make
