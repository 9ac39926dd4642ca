"""libcosim's ECCO beside `compare --tolerances` (`--peers ecco`): the scenario's FMUs run by libcosim
(through libcosimpy) under ECCO, its energy-conservation-based step control (Sadjina and Pedersen
2020, "Energy conservation and coupling error reduction in non-iterative co-simulations"), at each
tolerance, and measured as wavecosim's runs are: true error against the same fine reference, FMU
doSteps, wall time. ECCO never rejects a step, so its doSteps are its steps times its FMUs.

Each wavecosim port pair joined by `equal_effort_opposite_flow` whose values pass unchanged (one side
takes the effort, the other the flow, opposite signs) is one ECCO power bond: each side's output and
input value references, connected output to input.
"""
import math
import re
import time
from dataclasses import dataclass

import numpy as np

from ..bench.peers import Refused, in_child, libcosim, serve
from ..core.scene import resolve_fmu
from ..errors import ConfigError, optional
from ..run.fine import FINE_STEPS, true_error

PEERS = ("ecco",)
SAFETY, P_GAIN, I_GAIN = 0.8, 0.2, 0.15       # ECCO's controller: libcosimpy's EccoParams defaults (the paper's)
CHANGE_RATE = (0.2, 1.5)                      # bounds of h_new / h: libcosimc's tests/ecco_algorithm_multi_bond_test.c
TITLE = "libcosim's ECCO"


@dataclass(frozen=True)
class Bond:
    """One ECCO power bond: each side's instance, output and input, and their value references."""
    a: str
    a_out: str
    a_in: str
    b: str
    b_out: str
    b_in: str
    refs: tuple                                # (a_out, a_in, b_out, b_in) value references


def _channels(entry, subsystems):
    """[(subsystem, channel)] a coupling's port entry names: NAME (every channel) or NAME[k]."""
    match = re.fullmatch(r"(.+?)(?:\[(\d+)\])?", entry)
    name, k = match.group(1), match.group(2)
    sub = subsystems.get(name)
    if sub is None or "physical_out" not in sub.port:
        raise Refused(f"no power bond: {name}'s port is not a physical port (an effort and a flow, in and out)")
    return [(sub, int(k))] if k is not None else [(sub, i) for i in range(len(sub.port["physical_in"]))]


def _references(sub):
    """{variable name: (value reference, causality)} of a subsystem's FMU, from its model description."""
    from fmpy import read_model_description
    md = read_model_description(str(resolve_fmu(sub)), validate=False)
    return {v.name: (v.valueReference, v.causality) for v in md.modelVariables}


def _bond(a, i, b, j, refs):
    """The bond of channel i of a and channel j of b, or Refused where libcosim cannot pass it unchanged."""
    pa, pb = a.port, b.port
    if pa["input"][i] == pb["input"][j]:
        raise Refused(f"no power bond: {a.name} and {b.name} both take the {pa['input'][i]}")
    signs = (pa.get("sign") or [None] * (i + 1))[i], (pb.get("sign") or [None] * (j + 1))[j]
    if None in signs or signs[0] != -signs[1]:
        raise Refused(f"no power bond: {a.name} and {b.name} need declared, opposite signs to pass their values "
                      "unchanged")
    names = (pa["physical_out"][i], pa["physical_in"][i], pb["physical_out"][j], pb["physical_in"][j])
    owners = (a.name, a.name, b.name, b.name)
    for name, owner, causality in zip(names, owners, ("output", "input") * 2):
        if refs[owner].get(name, (None, None))[1] != causality:
            raise Refused(f"no power bond: {name} is not an {causality} of {owner}")
    return Bond(a.name, names[0], names[1], b.name, names[2], names[3],
                tuple(int(refs[o][n][0]) for n, o in zip(names, owners)))


def power_bonds(scenario):
    """The scenario's ECCO power bonds; Refused (one line) where it has none or more than they hold."""
    if scenario.signals or scenario.signal_subsystems or getattr(scenario, "sources", None):
        raise Refused("no power bond: ECCO here runs port pairs alone, and the system has signals")
    if scenario.start_time != 0.0:
        raise Refused(f"libcosimpy starts every execution at t = 0, the system at t = {scenario.start_time:g}")
    subsystems = {s.name: s for s in scenario.subsystems}
    refs = {name: _references(sub) for name, sub in subsystems.items()}
    bonds = []
    for c in scenario.couplings:
        if c.type != "equal_effort_opposite_flow":
            raise Refused(f"no power bond: a {c.type} coupling is not a plain connection")
        bonds += [_bond(a, i, b, j, refs) for (a, i), (b, j) in _pairs(c, subsystems)]
    if not bonds:
        raise Refused("no power bond: the system couples no physical ports")
    return bonds


def _pairs(coupling, subsystems):
    """The (subsystem, channel) pairs an equal_effort_opposite_flow coupling joins, channel by channel."""
    sides = [_channels(entry, subsystems) for entry in coupling.ports]
    if len(sides) != 2 or len(sides[0]) != len(sides[1]):
        raise Refused(f"no power bond: the coupling of {', '.join(coupling.ports)} does not join two ports channel "
                      "by channel")
    return list(zip(*sides))


def ecco_params(scenario, tolerance):
    """EccoParams' fields for a tolerance: rel_tolerance = tolerance, abs_tolerance = master.atol or
    the tolerance (libcosimpy's defaults keep the two equal); the first step dt, within dt_min
    (default dt / 1000, at least the span / FINE_STEPS) and dt_max (default span / 10)."""
    m, span = scenario.master, scenario.T - scenario.start_time
    lowest = max(m.dt_min or scenario.dt / 1000, span / FINE_STEPS)
    return {"safety_factor": SAFETY, "step_size": scenario.dt, "min_step_size": min(lowest, scenario.dt),
            "max_step_size": max(m.dt_max or span / 10, scenario.dt), "min_change_rate": CHANGE_RATE[0],
            "max_change_rate": CHANGE_RATE[1], "abs_tolerance": m.atol or tolerance, "rel_tolerance": tolerance,
            "p_gain": P_GAIN, "i_gain": I_GAIN}


def _request(scenario, bonds, tolerance, observed):
    """What the child process needs: FMUs, initial values, bonds, ECCO's parameters, the observed columns."""
    params = ecco_params(scenario, tolerance)
    return {"fmus": [(s.name, str(resolve_fmu(s))) for s in scenario.subsystems],
            "initial": {s.name: {**s.parameters, **s.start, **(s.integers or {})} for s in scenario.subsystems},
            "bonds": [[b.a, b.b, *b.refs] for b in bonds], "params": params,
            "stop": scenario.T, "observed": observed,
            "buffer": math.ceil((scenario.T - scenario.start_time) / params["min_step_size"]) + 16}


def _set_initial(execution, index, name, values):
    """Parameters and start values of one instance, each by its type in libcosim's model description."""
    from libcosimpy.CosimEnums import CosimVariableType as VT
    setters = {VT.REAL.value: execution.real_initial_value, VT.INTEGER.value: execution.integer_initial_value,
               VT.BOOLEAN.value: execution.boolean_initial_value, VT.STRING.value: execution.string_initial_value}
    by_name = {v.name.decode(): v for v in execution.slave_variables(index)}
    for var, value in values.items():
        v = by_name.get(var)
        if v is None:
            raise Refused(f"libcosim finds no variable {var!r} in {name}")
        if not setters[v.type](index, v.reference, value):
            raise Refused(f"libcosim refuses {name}.{var} = {value!r}")


def _build(request):
    """(execution, observer, {instance: index}) of an ECCO execution set up as the request says."""
    CosimExecution = libcosim()
    from libcosimpy.CosimAlgorithm import CosimAlgorithm, EccoParams
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    algorithm = CosimAlgorithm.create_ecco_algorithm(EccoParams(**request["params"]))
    execution = CosimExecution.from_algorithm(algorithm)
    execution.algorithm = algorithm                   # libcosim's execution uses it: it lives as long
    index = {name: execution.add_local_slave(CosimLocalSlave(fmu_path=path, instance_name=name))
             for name, path in request["fmus"]}
    for name, values in request["initial"].items():
        _set_initial(execution, index[name], name, values)
    observer = CosimObserver.create_time_series(buffer_size=request["buffer"])
    execution.add_observer(observer)
    for a, b, a_out, a_in, b_out, b_in in request["bonds"]:
        failed = (execution.connect_real_variables(index[a], a_out, index[b], b_in),     # 0 on success
                  execution.connect_real_variables(index[b], b_out, index[a], a_in))
        if any(failed) or algorithm.add_power_bond(index[a], a_out, a_in, index[b], b_out, b_in) != 0:
            raise Refused(f"libcosim refuses the power bond of {a} and {b}")
        for i, vr in ((a, a_out), (a, a_in), (b, b_out), (b, b_in)):   # ECCO reads them through the observer
            observer.start_time_series(index[i], vr, CosimVariableType.REAL)
    return execution, observer, index


def run_ecco(request):
    """In the child: the ECCO run; {"t", "values" {column: samples}, "steps", "wall_time_s"}."""
    from libcosimpy.CosimEnums import CosimVariableType
    started = time.perf_counter()
    execution, observer, index = _build(request)
    refs = {}
    for column, name, var in request["observed"]:
        v = {v.name.decode(): v for v in execution.slave_variables(index[name])}.get(var)
        if v is not None and v.type == CosimVariableType.REAL.value:
            refs[column] = (index[name], v.reference)
            observer.start_time_series(index[name], v.reference, CosimVariableType.REAL)
    if not execution.simulate_until(int(round(request["stop"] * 1e9))):
        from libcosimpy._internal import get_last_error_message
        raise Refused(f"{TITLE} fails: {get_last_error_message().strip() or 'its step failed'}")
    wall = time.perf_counter() - started
    out = {"values": {}, "wall_time_s": wall}
    for column, (i, vr) in refs.items():
        first = observer.time_series_real_samples(i, vr, 0, 2)          # step 0 (read alone: libcosimpy
        rest = observer.time_series_real_samples(i, vr, 1, request["buffer"])  # cuts a series at step 0)
        out["t"] = [t * 1e-9 for t in first[0] + rest[0]]
        out["steps"] = rest[1][-1] if rest[1] else 0
        out["values"][column] = list(first[2] + rest[2])
    return out


def child():
    """The child process's entry: run_ecco on the request in argv[1], the answer in argv[2]."""
    serve(run_ecco, TITLE)


@dataclass
class Trajectory:
    """A peer's samples at its own times, read as true_error reads a run's result."""
    t: np.ndarray
    values: dict

    @property
    def columns(self):
        return list(self.values)

    error_columns = columns

    def column(self, name):
        return self.values[name]


def observed_columns(scenario, reference):
    """[(column, instance, variable)] of the reference's error columns (else every column) that are
    variables of the scenario's FMUs."""
    names = {s.name for s in scenario.subsystems}
    out = []
    for column in reference.error_columns or reference.columns:
        instance, _, var = scenario.outputs.get(column, column).partition(".")
        if instance in names and var:
            out.append((column, instance, var))
    return out


def ecco_row(scenario, bonds, tolerance, reference):
    """One ECCO run at a tolerance and its row of tolerances.csv (a failure is a row saying so)."""
    row = {"mode": "ecco", "master": "libcosim", "K": "", "tolerance": tolerance, "dt": scenario.dt}
    request = _request(scenario, bonds, tolerance, observed_columns(scenario, reference))
    try:
        out = in_child("wavecosim.sweeps.ecco", request, TITLE)
    except Refused as exc:
        return {**row, "status": f"failed: {exc}", "true_error": math.nan}
    t = np.asarray(out["t"])
    kept = t <= scenario.T + 1e-12 * max(1.0, scenario.T)        # ECCO's last step may pass T
    run = Trajectory(t[kept], {c: np.asarray(v, float)[kept] for c, v in out["values"].items()})
    return {**row, "true_error": true_error(run, reference)["true_error"],
            "doStep": out["steps"] * len(scenario.subsystems), "save": 0, "restore": 0,
            "wall_time_s": out["wall_time_s"], "accepted_steps": out["steps"], "rejected_steps": 0,
            "max_ledger": "", "status": "finished"}


def peer_rows(scenario, tolerances, reference, peers=(), progress=None, note=None):
    """The rows of the peers asked for (PEERS) at each tolerance; a peer that cannot run the system
    is one line to `note` and no rows."""
    rows = []
    if "ecco" not in peers:
        return rows
    try:
        optional("libcosimpy", "peers", "--peers ecco")
        bonds = power_bonds(scenario)
    except (Refused, ConfigError) as exc:        # not installed (the line names the extra), or no power bond
        if note:
            note(f"{TITLE} skipped: {exc}")
        return rows
    for tol in tolerances:
        rows.append(ecco_row(scenario, bonds, tol, reference))
        if progress:
            progress(rows[-1])
    return rows
