"""The compatibility table (docs/compatibility.md): every system of ../shared/third_party run through
wavecosim as a user would run it, compared with what its peer prints for it (the README there:
OMSimulator's test scripts) and, for every run without iteration, with a plain fmpy loop over the
same FMUs (doStep(t_n, dt), inputs set from the outputs at t_n), which it must equal to the last bit;
and, a column per peer (libcosim, FMPy, Ecos where it imports), with the peers' own runs of the file
(wavecosim/bench/peers.py, the comparisons tests/peers/test_peers.py makes).

    .venv/bin/python scripts/compatibility.py [--third-party DIR] [--out docs/compatibility.md] [--only NAME]

Rows of systems that are absent are left out; a row whose run fails says why. Takes a few minutes
(the dual mass oscillator makes 10^5 macro-steps twice, the first run of pwmtest builds its FMUs)."""
import argparse
import dataclasses
import math
import re
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

import fmpy
import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2LastSuccessfulTime, fmi2Terminated
from fmpy.fmi3 import FMU3Slave

import wavecosim as wc
from wavecosim.bench import peers
from wavecosim.errors import WavecosimError
from wavecosim.fmi.builtin import builtin_fmus

ROOT = Path(__file__).resolve().parent.parent
THIRD_PARTY = ROOT.parent / "shared" / "third_party"
FMI2_CALLS = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean", "String": "String"}
REAL_TYPES = ("Real", "Float64", "Float32")


# --- a plain fmpy loop --------------------------------------------------------------------------

class Plain:
    """One FMU stepped by fmpy, addressed by variable names, set up as wavecosim sets it up."""

    def __init__(self, sub, folder, start_time):
        path = str(sub.fmu_path or builtin_fmus()[sub.fmu])
        md = read_model_description(path, validate=False)
        self.fmi3 = md.fmiVersion.startswith("3")
        self.vars = {v.name: v for v in md.modelVariables}
        slave = (FMU3Slave if self.fmi3 else FMU2Slave)(
            guid=md.guid, unzipDirectory=extract(path, unzipdir=str(folder / sub.name)),
            modelIdentifier=md.coSimulation.modelIdentifier, instanceName=sub.name)
        slave.instantiate()
        experiment = md.defaultExperiment
        tolerance = getattr(sub, "tolerance", None) or (float(experiment.tolerance)
                                                         if experiment is not None and experiment.tolerance else None)
        if not self.fmi3:
            slave.setupExperiment(tolerance=tolerance, startTime=start_time)
        self.slave = slave
        for name, value in {**sub.parameters, **sub.start, **sub.integers}.items():
            self.set(name, value)
        if self.fmi3:
            slave.enterInitializationMode(tolerance=tolerance, startTime=start_time)
        else:
            slave.enterInitializationMode()

    def kind(self, name):
        """The FMI type of a variable."""
        return self.vars[name].type

    def _call(self, name):
        """fmpy's get/set suffix for a variable: Real, Integer, Boolean (FMI 2); Float64, Int32, ... (FMI 3)."""
        kind = self.kind(name)
        return ("Int64" if kind == "Enumeration" else kind) if self.fmi3 else FMI2_CALLS[kind]

    def get(self, name):
        value = getattr(self.slave, f"get{self._call(name)}")([self.vars[name].valueReference])[0]
        if self.kind(name) == "Binary":
            return bytes(value).hex()
        return value.decode() if isinstance(value, bytes) else value if isinstance(value, str) else float(value)

    def set(self, name, value):
        call = self._call(name)
        cast = bool if call == "Boolean" else str if call == "String" else float if self.kind(name) in REAL_TYPES else int
        getattr(self.slave, f"set{call}")([self.vars[name].valueReference], [cast(value)])

    def step(self, t, dt):
        """One doStep; None, or where the FMU asked to end the simulation: "last" when it completed the
        step (recorded, then the run ends), "before" when it did not (as fmpy's simulate ends)."""
        if self.fmi3:
            _, terminate, _, last = self.slave.doStep(t, dt)
        else:
            try:
                self.slave.doStep(t, dt)
                return None
            except FMICallException as exc:
                if exc.status != 2 or not self.slave.getBooleanStatus(fmi2Terminated):
                    raise
                terminate, last = True, self.slave.getRealStatus(fmi2LastSuccessfulTime)
        return ("last" if math.isclose(last, t + dt) else "before") if terminate else None

    def end_initialization(self):
        self.slave.exitInitializationMode()

    def close(self):
        self.slave.terminate()
        self.slave.freeInstance()


def recorded(scenario, result):
    """{column: SUBSYSTEM.variable} of what a run recorded (a default column is named after its variable)."""
    return {col: scenario.outputs.get(col, col) for col in result.trajectory.dtype.names[1:]}


def plain_loop(scenario, columns):
    """{column: values at every grid point} of `columns` ({column: SUBSYSTEM.variable}), from a plain
    fmpy loop over the scenario's subsystems (signals only): in initialization mode, inputs set from
    the outputs until no value changes (as libcosim and FMPy settle a system); then per step inputs
    set from the outputs (and tables) at t_n, and one doStep each."""
    t0 = getattr(scenario, "start_time", 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        fmus = {s.name: Plain(s, Path(tmp), t0) for s in scenario.signal_subsystems}
        tables = {s.name: s for s in scenario.sources}
        rows = []

        def hold(t):
            values = []
            for sig in scenario.signals:
                name, var = sig.source.split(".", 1)
                v = (float(np.interp(t, tables[name].times, tables[name].columns[var])) if name in tables
                     else fmus[name].get(var))
                target, var = sig.target.split(".", 1)
                values.append(sig.factor * v + sig.offset if fmus[target].kind(var) in REAL_TYPES else v)
            for sig, v in zip(scenario.signals, values):
                name, var = sig.target.split(".", 1)
                fmus[name].set(var, v)
            return values

        def record():
            rows.append([fmus[ref.split(".", 1)[0]].get(ref.split(".", 1)[1]) for ref in columns.values()])

        last = None
        for _ in range(len(fmus) + 4):
            values = hold(t0)
            if values == last:
                break
            last = values
        for fmu in fmus.values():
            fmu.end_initialization()
        hold(t0)
        record()
        for n in range(scenario.n_steps):
            t = t0 + n * scenario.dt
            hold(t)
            ends = {fmu.step(t, scenario.dt) for fmu in fmus.values()}
            if "before" not in ends:
                record()
            if ends - {None}:
                break
        for fmu in fmus.values():
            fmu.close()
    return {col: np.array([row[j] for row in rows]) for j, col in enumerate(columns)}


# --- runs ---------------------------------------------------------------------------------------

def load(path, outputs=None, **settings):
    """The scenario of `path` as `wavecosim run` reads it, recording `outputs` ({column: ref}) too."""
    notes = []
    scenario = wc.load(path, warn=notes.append, **settings)
    if outputs:
        scenario = dataclasses.replace(scenario, outputs={**scenario.outputs, **outputs})
    return scenario, notes


def simulate(scenario):
    started = time.perf_counter()
    result = wc.simulate(scenario, reference=False, certificates=False)
    return result, time.perf_counter() - started


def same_as_plain_loop(scenario, result):
    """'equal to a plain fmpy loop, bit for bit' or where it differs."""
    columns = recorded(scenario, result)
    expected = plain_loop(scenario, columns)
    traj = result.trajectory
    if len(traj) != len(next(iter(expected.values()), traj)):
        return False, f"{len(traj)} rows, a plain fmpy loop has {len(next(iter(expected.values())))}"
    worst = [(col, float(np.max(np.abs(traj[col] - expected[col]))) if traj[col].dtype.kind == "f" else math.nan)
             for col in columns if not np.array_equal(traj[col], expected[col])]
    if not worst:
        return True, f"equal to a plain fmpy loop, bit for bit ({len(columns)} column{'s' if len(columns) != 1 else ''}, {len(traj)} rows)"
    col, diff = max(worst, key=lambda w: w[1])
    return False, f"differs from a plain fmpy loop in {len(worst)} columns (worst {col}: {diff:.3g})"


def values(result, row, checks):
    """[(ok, 'at t: name = ours (peer), ...')] for {column: peer value} at trajectory row `row`."""
    traj = result.trajectory
    found = [(float(traj[col][row]), col, peer) for col, peer in checks.items()]
    text = ", ".join(f"{col} = {ours!r} ({peer!r})" for ours, col, peer in found)
    return [(all(ours == peer for ours, _, peer in found), f"at t = {float(traj['time'][row]):g}: {text}")]


def verdict(parts):
    """A table cell from [(ok, text)]: 'OK: ...' or 'DIFFERS: ...'."""
    ok = all(p[0] for p in parts)
    return ok, ("OK: " if ok else "DIFFERS: ") + "; ".join(p[1] for p in parts)


# --- the systems --------------------------------------------------------------------------------

def linear_transformation(tp):
    scenario, _ = load(tp / "omsimulator/LinearTransformation/SystemStructure.ssd",
                       outputs={"Gain1.y": "Gain1.y", "Add1.u1": "Add1.u1"})
    result, s = simulate(scenario)
    return verdict(values(result, -1, {"Gain1.y": 0.0, "Add1.u1": 3.0}) + [same_as_plain_loop(scenario, result)]), s


def linear_transformation3(tp):
    extra = {k: k for k in ("Gain1.k", "Gain1.u", "Gain1.y", "Add1.u1")}
    scenario, _ = load(tp / "omsimulator/LinearTransformation3/SystemStructure.ssd", outputs=extra)
    result, s = simulate(scenario)
    parts = values(result, 0, {"Gain1.k": 13.0, "Gain1.u": 14.0, "Gain1.y": 182.0})
    parts += values(result, -1, {"Gain1.k": 13.0, "Gain1.u": 14.0, "Gain1.y": 182.0, "Add1.u1": 182.0})
    return verdict(parts + [same_as_plain_loop(scenario, result)]), s


def import_export_parameters(tp):
    scenario, _ = load(tp / "omsimulator/import_export_parameters1/SystemStructure.ssd")
    result, s = simulate(scenario)
    parts = values(result, -1, {"addP.k1": 30.0, "addI.k2": 20.0, "addP.u1": -20.0, "addP.y": -600.0,
                                "Output_cref": -600.0})
    return verdict(parts + [same_as_plain_loop(scenario, result)]), s


def pwmtest(tp):
    scenario, _ = load(tp / "omsimulator/pwmtest/SystemStructure.ssd")
    result, s = simulate(scenario)
    traj = result.trajectory
    R, L = float(traj["circuit.resistor.R"][0]), float(traj["circuit.inductor.L"][0])
    decay = math.exp(-R * scenario.dt / L)
    current = np.zeros(len(traj))          # the exact response of L di/dt = -(R i + u) to u held over each step
    for n in range(len(traj) - 1):
        current[n + 1] = current[n] * decay - traj["circuit.u"][n + 1] / R * (1 - decay)
    err = float(np.max(np.abs(traj["circuit.inductor.i"] - current)) / np.max(np.abs(current)))
    return verdict([(err < 1e-4, f"{len(traj) - 1} steps; the model-exchange circuit's current meets the exact "
                                 f"response to the held pulse to {err:.1e} (relative to its peak; CVode at "
                                 f"tolerance 1e-6); OMSimulator prints nothing (its test is marked linux: no)")]), s


EMBRACE_L = {"ECS_HW.pipeA.L": 0.976535328081166, "ECS_HW.pipeB.L": 0.976535328081166, "ECS_HW.pipeC.L": 1.0}


def embrace(tp):
    extra = {k: k for k in EMBRACE_L}
    scenario, _ = load(tp / "omsimulator/embrace/SystemStructure.ssd", outputs=extra, T=1.0)
    result, s = simulate(scenario)
    return verdict(values(result, 0, EMBRACE_L) + [(True, f"{scenario.n_steps} steps of {scenario.dt:g} s")]
                   + [same_as_plain_loop(scenario, result)]), s


BC = ('<ssd:Component name="BC" type="application/table" source="{csv}"><ssd:Connectors>'
      + "".join(f'<ssd:Connector name="{c}" kind="output"><ssc:Real/></ssd:Connector>'
                for c in ("Alt", "Mach", "heatLoad", "WGT_ON_WHL", "Aircraft_state"))
      + '</ssd:Connectors></ssd:Component>')
BC_LINKS = [("Consumer", "Alt", "Alt"), ("Consumer", "Mach", "Mach"), ("Consumer", "heatLoad", "heatLoad"),
            ("ECS_HW", "Alt", "Alt"), ("ECS_HW", "Mach", "Mach"), ("AdaptionUnit", "Aircraft_State", "Aircraft_state"),
            ("Atmos", "Alt", "Alt"), ("Atmos", "Ma", "Mach")]
SETTINGS = {"eCS.MaxCoolPower.k": ("Real", 5.0), "coolinPackAir.looptype": ("Integer", 2),
            "phSrc.looptype": ("Integer", 2), "pipeB.looptype": ("Integer", 2), "pipeA.looptype": ("Integer", 2)}


def embrace_with_conops(tp, folder):
    """The SSD OMSimulator's embrace1.py makes: CONOPS.csv as the table component BC connected to
    the boundary inputs, MaxCoolPower.k = 5 and four looptype parameters = 2 (here an inline binding)."""
    base = tp / "omsimulator/embrace"
    text = (base / "SystemStructure.ssd").read_text()
    text = re.sub(r'(source|signalFilter)="resources/', rf'\1="{base}/resources/', text)
    params = "".join(f'<ssv:Parameter name="{k}"><ssv:{t} value="{v}"/></ssv:Parameter>' for k, (t, v) in SETTINGS.items())
    binding = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" '
               f'name="embrace1"><ssv:Parameters>{params}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
               '</ssd:ParameterBinding></ssd:ParameterBindings>')
    hw = text.index('<ssd:Component name="ECS_HW"')
    end = text.index("</ssd:Connectors>", hw) + len("</ssd:Connectors>")
    text = text[:end] + binding + text[end:]
    text = text.replace("</ssd:Elements>", BC.format(csv=base / "CONOPS.csv") + "</ssd:Elements>", 1)
    links = "".join(f'<ssd:Connection startElement="BC" startConnector="{c}" endElement="{e}" endConnector="{i}"/>'
                    for e, i, c in BC_LINKS)
    text = text.replace("</ssd:Connections>", links + "</ssd:Connections>", 1)
    path = folder / "embrace1.ssd"
    path.write_text(text)
    extra = {k: k for k in EMBRACE_L} | {f"ECS_HW.{k}": f"ECS_HW.{k}" for k in SETTINGS}
    scenario, _ = load(path, outputs=extra, T=1.0)
    result, s = simulate(scenario)
    peer = {**EMBRACE_L, **{f"ECS_HW.{k}": float(v) for k, (_, v) in SETTINGS.items()}}
    return verdict(values(result, 0, peer) + [same_as_plain_loop(scenario, result)]), s


def dcmotor(tp):
    scenario, notes = load(tp / "dcmotor/SystemStructure.ssd")
    result, s = simulate(scenario)
    return verdict([(True, f"the file alone: explicit, dt = {scenario.dt:g} s, T = {scenario.T:g} s; wB(T) = "
                           f"{result.trajectory['wB'][-1]:.6g} rad/s"), same_as_plain_loop(scenario, result)]), s


def dcmotor_overlay(tp):
    ssd, _ = load(tp / "dcmotor/SystemStructure.ssd", ports=ROOT / "configs/dcmotor_ports.yaml", T=0.05)
    yaml, _ = load(ROOT / "configs/dcmotor.yaml", T=0.05)
    started = time.perf_counter()
    a = wc.simulate(ssd, reference=False, certificates=False).trajectory
    b = wc.simulate(yaml, reference=False, certificates=False).trajectory
    same = all(np.array_equal(a[n], b[n]) for n in b.dtype.names)
    return verdict([(same, f"DR K = {ssd.master.K} over 0.05 s: " + ("the same bits as configs/dcmotor.yaml"
                                                                   if same else "differs from configs/dcmotor.yaml"))]), \
        time.perf_counter() - started


DMO = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="DualMassOscillator"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="default"><ssd:Elements>{components}</ssd:Elements><ssd:Connections>{connections}</ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="10"/>
</ssd:SystemStructureDescription>
"""
DMO_PEER = {"system1.x1": 0.051412690223479836, "system2.x2": 0.031858470461315964}


def dual_mass_ssd(tp, folder):
    """The system OMSimulator's DualMassOscillator.py builds: F from system2 to system1; x1, v1, a1 back;
    x1_start = 0, x2_start = 0.5."""
    comps = "".join(
        f'<ssd:Component name="system{i}" source="{tp}/dual_mass_oscillator/DualMassOscillator.System{i}.fmu">'
        f'<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p">'
        f'<ssv:Parameters><ssv:Parameter name="x{i}_start"><ssv:Real value="{v}"/></ssv:Parameter></ssv:Parameters>'
        f'</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings></ssd:Component>'
        for i, v in ((1, 0.0), (2, 0.5)))
    conns = '<ssd:Connection startElement="system2" startConnector="F" endElement="system1" endConnector="F"/>' + "".join(
        f'<ssd:Connection startElement="system1" startConnector="{v}" endElement="system2" endConnector="{v}"/>'
        for v in ("x1", "v1", "a1"))
    path = folder / "DualMassOscillator.ssd"
    path.write_text(DMO.format(components=comps, connections=conns))
    return path


DMO_PORTS = """ports:
  system1: {physical_in: F, physical_out: v1, input: effort, sign: 1}
  system2: {physical_in: v1, physical_out: F, input: flow}
"""


def dual_mass_oscillator(tp, folder):
    path = dual_mass_ssd(tp, folder)
    scenario, _ = load(path, outputs={k: k for k in DMO_PEER}, dt=1e-4)
    result, s = simulate(scenario)
    parts = [(True, "explicit, dt = 1e-4 s, T = 10 s: " + ", ".join(
        f"{k} = {result.trajectory[k][-1]:.6g} (OMSimulator {v:.6g}, {abs(result.trajectory[k][-1] / v - 1):.1%} apart)"
        for k, v in DMO_PEER.items()))]
    (folder / "ports.yaml").write_text(DMO_PORTS)
    try:
        wc.load(path, ports=folder / "ports.yaml", master="dr", T=0.01)
        wc.simulate(wc.load(path, ports=folder / "ports.yaml", master="dr", T=0.01), certificates=False)
        parts.append((False, "dr with the shaft as a port ran, but these FMUs cannot restore their state"))
    except WavecosimError as exc:
        parts.append(("cannot get and set its state" in str(exc),
                      f"dr with the force/velocity port refused: {str(exc).split(': ', 2)[-1]}"))
    return verdict(parts + [same_as_plain_loop(scenario, result)]), s


def md_outputs(md):
    return [v for v in md.modelVariables if v.causality == "output"]


def single_fmu(path):
    """`wavecosim run X.fmu` (with --dt 0.01 and 1 s from its start time where its DefaultExperiment
    gives no step size, as one runs fmizoo's IO.fmu); an FMU with no co-simulation interface is
    refused in one line."""
    md = read_model_description(str(path), validate=False)
    experiment, given = md.defaultExperiment, {}
    if experiment is None or experiment.stepSize is None:
        start = float(experiment.startTime) if experiment is not None and experiment.startTime else 0.0
        given.update(dt=0.01, T=start + 1.0)
    if md.coSimulation is None:
        try:
            simulate(load(path, **given)[0])
        except WavecosimError as exc:
            return (True, f"refused in one line, as it has no co-simulation interface: {exc}"), math.nan
    scenario, _ = load(path, **given)
    name = scenario.signal_subsystems[0].name
    states = {f"{name}.{d.variable.derivative.name}": f"{name}.{d.variable.derivative.name}"
              for d in md.derivatives if d.variable.derivative is not None}
    if states and not md_outputs(md):                  # nothing to record by default: its states
        scenario = dataclasses.replace(scenario, outputs=states)
    result, s = simulate(scenario)
    options = " ".join(f"--{k} {v:g}" for k, v in given.items())
    made, traj = len(result.trajectory) - 1, result.trajectory
    ended = f", the FMU ended the run at t = {traj['time'][-1]:g}" if made < scenario.n_steps else ""
    return verdict([(True, f"{made} steps of {scenario.dt:g} s" + (f" ({options})" if options else "") + ended),
                    same_as_plain_loop(scenario, result)]), s


# --- the table ----------------------------------------------------------------------------------

def rows(tp, folder):
    """(system, what it exercises, runner) of every system in the corpus."""
    out = [
        ("omsimulator/LinearTransformation", "ssc:LinearTransformation factor 2, offset 3; stop time from the SSD; "
         "step from the FMUs", lambda: linear_transformation(tp)),
        ("omsimulator/LinearTransformation3", ".ssv binding through an .ssm ParameterMapping with linear "
         "transformations; SSP 2.0", lambda: linear_transformation3(tp)),
        ("omsimulator/import_export_parameters1", "system connectors (startElement=\"\") both ways, parameters as "
         "top-level connectors, .ssv, signal filter", lambda: import_export_parameters(tp)),
        ("omsimulator/pwmtest", "nested system, system connectors, signal filter; win64-only source FMUs (built "
         "here), a model-exchange-only FMU", lambda: pwmtest(tp)),
        ("omsimulator/embrace (--T 1)", "five Dymola/Simulink FMUs, Integer and Enumeration signals, .ssm "
         "mapping one value to two parameters, OMSimulator's fixed step and signal filter", lambda: embrace(tp)),
        ("omsimulator/embrace + CONOPS.csv as BC", "what embrace1.py builds: a CSV table component, "
         "MaxCoolPower.k = 5, looptype = 2", lambda: embrace_with_conops(tp, folder)),
        ("dcmotor", "nested systems, unit conversions (N.m, Nm), no DefaultExperiment: the file alone",
         lambda: dcmotor(tp)),
        ("dcmotor + configs/dcmotor_ports.yaml", "the shaft as a power bond: DR", lambda: dcmotor_overlay(tp)),
        ("dual_mass_oscillator", "FMUs without state save (SSD as OMSimulator's DualMassOscillator.py builds it)",
         lambda: dual_mass_oscillator(tp, folder)),
    ]
    for group in ("fmizoo", "reference_fmus"):
        for fmu in sorted((tp / group).glob("fmi*/*.fmu")):
            version = fmu.parent.name.replace("fmi", "FMI ")
            out.append((f"{group}/{fmu.parent.name}/{fmu.name}", f"a single {version} FMU", lambda f=fmu: single_fmu(f)))
    return out


# --- the peers as oracles (wavecosim/bench/peers.py, as tests/peers/test_peers.py runs them) --------

def the_file_alone(path):
    """The row of a corpus system that no row above covers: the explicit master on the file alone."""
    started = time.perf_counter()
    scenario = peers.load_system(path)
    made = len(next(iter(peers.ours(scenario).values()), []))
    return (True, f"the file alone: explicit, dt = {scenario.dt:g} s, {max(made - 1, 0)} steps"), \
        time.perf_counter() - started


def peer_cell(path, peer):
    """A peer's cell: its agreement with the explicit master on the file, or why it has none."""
    try:
        scenario = peers.load_system(path)
        errors = peers.compare(scenario, path, peer)
    except WavecosimError as exc:
        return True, f"– (wavecosim refuses the file: {str(exc).rsplit(': ', 1)[-1]})"
    except peers.Refused as exc:
        return True, str(exc).replace(str(ROOT), ".")
    return peers.verdict(peer, path, scenario, errors)


def peer_cells(path, names):
    """The peers' cells of a row ('–' for a row that is a variant of a corpus system), and whether
    every one is an agreement, a known deviation or a refusal."""
    if path is None:
        return True, ["–"] * len(names)
    cells = [peer_cell(path, peer) for peer in names]
    return all(ok for ok, _ in cells), [text for _, text in cells]


def table(tp, only=None, progress=print):
    """The Markdown table and whether every row passed."""
    names = [p for p in peers.PEERS if p != "ecos" or peers.installed("ecos")]
    lines = ["| system | what it exercises | result (peer's value in parentheses) | run s | "
             + " | ".join(peers.TITLES[p] for p in names) + " |", "|---|---|---|---|" + "---|" * len(names)]
    passed = True
    corpus = dict(peers.corpus(tp, sorted((ROOT / "configs").glob("*.ssd"))))
    with tempfile.TemporaryDirectory() as tmp:
        listed = rows(tp, Path(tmp))
        covered = {name.split(" (")[0] for name, _, _ in listed}
        listed += [(name, "the file alone" + (", an in-repo scene" if path.parent == ROOT / "configs" else ""),
                    lambda p=path: the_file_alone(p)) for name, path in corpus.items() if name not in covered]
        for name, what, runner in listed:
            if only and only not in name:
                continue
            progress(f"  {name} ...")
            try:
                (ok, text), seconds = runner()
            except Exception as exc:                # a row that cannot run says why; the others go on
                ok, text, seconds = False, f"FAILS: {type(exc).__name__}: {exc}", math.nan
            agree, cells = peer_cells(corpus.get(name.split(" (")[0]), names)
            passed &= ok and agree
            lines.append(f"| {name} | {what} | {text.replace('|', '/')} | {seconds:.1f} | "
                         + " | ".join(c.replace("|", "/") for c in cells) + " |")
    return "\n".join(lines), passed


HEADER = """# Compatibility with the systems users already have

Every system of `../shared/third_party` (real files nobody here wrote; their README says where
they come from and what the peer prints) run as a user runs it, and compared with the peer's
printed values (OMSimulator's test scripts) and with a plain fmpy loop over the same FMUs
(`doStep(t_n, Δt)`, inputs from the outputs at t_n), which a run without iteration equals to the
last bit. Regenerate this page with

    .venv/bin/python scripts/compatibility.py

The peer columns run each file (the in-repo `configs/*.ssd` scenes too) through a peer in a
process of its own and through wavecosim's explicit master, at most 200 macro-steps of the file's
step (0.01 s over 1 s for an FMU whose DefaultExperiment gives none), and compare every Real output column both record:
`agrees` when max |Δy| / the column's range in the peer's run is at most 10⁻⁹, `differs as
expected` with the reason (the FMUs' DefaultExperiment tolerance, which wavecosim passes to their
set-up and libcosim and Ecos do not; a peer's known gap), else `DIFFERS`; a peer that cannot run
the file says why in its words. libcosim is libcosimpy 0.0.6 (libcosim 0.11, FMI 2 only), FMPy
its `simulate_fmu` (single FMUs; a system's plain fmpy loop is in the result column), Ecos
ecospy 0.7.2 (SSP 1.0 only), where it imports (it needs the system's libtbb.so.12).
`tests/peers/test_peers.py` makes the same comparisons (`make test-slow`).

"""


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--third-party", type=Path, default=THIRD_PARTY)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "compatibility.md")
    parser.add_argument("--only", help="only the rows whose system holds this text (the page is not written)")
    args = parser.parse_args(argv)
    if not args.third_party.exists():
        sys.exit(f"{args.third_party}: the third-party corpus is absent")
    text, passed = table(args.third_party, args.only, progress=lambda m: print(m, file=sys.stderr, flush=True))
    installed = [f"{m} {version(m)}" for p, m in peers.MODULES.items() if p != "fmpy" and peers.installed(p)]
    footer = (f"\nwavecosim {version('wavecosim')}, fmpy {fmpy.__version__}, {', '.join(installed + [''])}"
              f"Python {sys.version.split()[0]}.\n")
    if args.only:
        print(text)
    else:
        args.out.write_text(HEADER + text + "\n" + footer, encoding="utf-8")
        print(f"wrote {args.out}")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
