"""The peers as oracles: a system (an SSP system or one FMU) run by wavecosim's explicit master and
by a peer (libcosim through libcosimpy, FMPy's simulate_fmu for one FMU, Ecos through ecospy), and
every common output column compared, max |Δy| / the column's scale (run/observers/errors.py: its range in the peer's
run) against AGREE.

Each peer runs in a child process of its own: libcosim aborts the process on some files (an
Enumeration connector), and a peer that refuses a file is one line saying why (`Refused`).
The peers are the `peers` extra (`pip install 'wavecosim[peers]'`); Ecos needs the system's
libtbb (Debian: libtbb12) and is used where it imports.
"""
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..errors import ConfigError, optional
from ..run.observers.errors import column_scales

AGREE = 1e-9                 # max |Δy| / range at or below this: the peer and wavecosim agree
TOLERANCE_SPREAD = 100       # an integrator's tolerance tol moves a column by at most this x tol of its range
CHILD_TIMEOUT_S = 600        # a peer's child process that runs longer is stopped
PEERS = ("libcosim", "fmpy", "ecos")
MODULES = {"libcosim": "libcosimpy", "ecos": "ecospy", "fmpy": "fmpy"}
TITLES = {"libcosim": "libcosim", "fmpy": "FMPy", "ecos": "Ecos"}


class Refused(Exception):
    """The peer cannot run the file (refuses it, aborts on it, or is not installed); str: why, one line."""


def libcosim():
    """libcosimpy imported, or a ConfigError naming the `peers` extra; its log kept to errors."""
    optional("libcosimpy", "peers", "the libcosim peer")
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.ERROR)
    from libcosimpy.CosimExecution import CosimExecution
    return CosimExecution


def installed(peer):
    """Whether a peer's Python package imports here (Ecos also needs the system's libtbb)."""
    try:
        optional(MODULES[peer], "peers", peer)
        return True
    except Exception:                    # ConfigError, or ecospy's OSError without libtbb
        return False


def libcosim_execution(system, dt, instance=None):
    """libcosim's CosimExecution of an SSP system (folder or .ssd) or one FMU (named `instance`, else
    by its file), macro-step dt; Refused with libcosim's reason where it cannot load it."""
    CosimExecution = libcosim()
    system, step = Path(system), int(round(dt * 1e9))
    try:
        if system.suffix == ".fmu":
            from libcosimpy.CosimSlave import CosimLocalSlave
            execution = CosimExecution.from_step_size(step_size=step)
            execution.add_local_slave(CosimLocalSlave(fmu_path=str(system), instance_name=instance or system.stem))
            return execution
        return CosimExecution.from_ssp_file(ssp_path=str(system.parent if system.suffix == ".ssd" else system),
                                            step_size=step)
    except Exception as exc:            # libcosimpy raises bare exceptions
        raise Refused(f"libcosim refuses it: {str(exc).strip() or type(exc).__name__}") from None


def _libcosim(system, dt, steps, refs, start_time):
    """{ref: values at grid points 0 .. steps} of the Real variables libcosim has among refs."""
    libcosim()
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimObserver import CosimObserver
    if start_time != 0.0:
        raise Refused(f"libcosimpy starts every execution at t = 0, the system at t = {start_time:g}")
    execution = libcosim_execution(system, dt, refs[0][1] if refs else None)
    observer = CosimObserver.create_time_series(buffer_size=steps + 16)
    execution.add_observer(observer)
    slaves = {s.name.decode(): s.index for s in execution.slave_infos()}
    found = {}
    for ref, name, var in refs:
        if name in slaves:
            by_name = {v.name.decode(): v for v in execution.slave_variables(slaves[name])}
            v = by_name.get(var)
            if v is not None and v.type == CosimVariableType.REAL.value:
                found[ref] = (slaves[name], v.reference)
                observer.start_time_series(slaves[name], v.reference, CosimVariableType.REAL)
    if not execution.step(steps + 1):
        raise Refused("libcosim's step failed")
    out = {}
    for ref, (index, vr) in found.items():
        _, _, values = observer.time_series_real_samples(index, vr, 0, steps + 1)
        out[ref] = list(values)
    return out


def _fmpy(system, dt, steps, refs, start_time):
    """{ref: values at grid points 0 .. steps} from fmpy's simulate_fmu (one FMU; its tolerance passed)."""
    from fmpy import read_model_description, simulate_fmu
    system = Path(system)
    if system.suffix != ".fmu":
        raise Refused("FMPy's simulate_fmu runs single FMUs")
    md = read_model_description(str(system), validate=False)
    if md.coSimulation is None:
        raise Refused("no co-simulation interface")
    names = {ref: var for ref, _, var in refs}          # one FMU: every column is a variable of it
    reals = {v.name for v in md.modelVariables if v.type in ("Real", "Float64", "Float32")}
    names = {ref: var for ref, var in names.items() if var in reals}
    result = simulate_fmu(str(system), validate=False, start_time=start_time, stop_time=start_time + steps * dt,
                          step_size=dt, output_interval=dt, output=list(dict.fromkeys(names.values())),
                          fmi_type="CoSimulation")
    return {ref: result[var].tolist() for ref, var in names.items()}


def _ecos(system, dt, steps, refs, start_time):
    """{ref: values at grid points 0 .. steps} of the Real variables Ecos reads among refs."""
    optional("ecospy", "peers", "the Ecos peer")
    from ecospy import EcosSimulation, EcosSimulationStructure
    system = Path(system)
    try:
        if system.suffix == ".fmu":
            structure = EcosSimulationStructure()
            structure.add_model(refs[0][1] if refs else system.stem, str(system))
            sim = EcosSimulation(structure=structure, step_size=dt)
        else:
            sim = EcosSimulation(ssp_path=str(system.parent if system.suffix == ".ssd" else system), step_size=dt)
        sim.init(start_time)
    except Exception as exc:
        raise Refused(f"Ecos refuses it: {str(exc).strip() or type(exc).__name__}") from None
    found, names = {}, {}
    for ref, name, var in refs:
        try:
            found[ref], names[ref] = [sim.get_real(f"{name}::{var}")], f"{name}::{var}"
        except Exception:                   # not a Real variable of an instance Ecos has
            continue
    for _ in range(steps):
        sim.step(1)
        for ref, values in found.items():
            values.append(sim.get_real(names[ref]))
    sim.terminate()
    return found


RUNNERS = {"libcosim": _libcosim, "fmpy": _fmpy, "ecos": _ecos}


def serve(function, title):
    """In a child process: function(request read as JSON from argv[1]), its answer (JSON) written to
    argv[2]; a refusal, a missing extra or the peer's own failure is {"refused": one line}."""
    request = json.loads(Path(sys.argv[1]).read_text(encoding="utf-8"))
    try:
        out = function(request)
    except (Refused, ConfigError) as exc:          # refused, or not installed (the line names the extra)
        out = {"refused": str(exc)}
    except Exception as exc:                        # the peer's own failure, said in one line
        out = {"refused": f"{title} fails on it: {type(exc).__name__}: {exc}".splitlines()[0]}
    Path(sys.argv[2]).write_text(json.dumps(out))


def child():
    """The peers' child process: the runner the request names, on its system."""
    def values(request):
        return {"values": RUNNERS[request["peer"]](request["system"], request["dt"], request["steps"],
                                                   request["refs"], request["start_time"])}
    request = json.loads(Path(sys.argv[1]).read_text(encoding="utf-8"))
    serve(values, TITLES[request["peer"]])


def in_child(module, request, title):
    """The answer of `module`'s child() to `request` (JSON both ways), in a child process of its own;
    Refused says why there is none (refused, aborted, or over CHILD_TIMEOUT_S)."""
    with tempfile.TemporaryDirectory() as tmp:
        asked, answer = Path(tmp) / "request.json", Path(tmp) / "answer.json"
        asked.write_text(json.dumps(request))
        package = str(Path(__file__).resolve().parents[2])
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (package, os.environ.get("PYTHONPATH")) if p)}
        try:
            done = subprocess.run([sys.executable, "-c", f"from {module} import child; child()",
                                   str(asked), str(answer)], capture_output=True, text=True, env=env,
                                  timeout=CHILD_TIMEOUT_S, cwd=tmp)
        except subprocess.TimeoutExpired:
            raise Refused(f"{title} runs more than {CHILD_TIMEOUT_S} s on it") from None
        if not answer.exists():
            last = next((line.strip() for line in reversed(done.stderr.splitlines()) if line.strip()), "")
            how = signal.Signals(-done.returncode).name if done.returncode < 0 else f"exit {done.returncode}"
            raise Refused(f"{title} aborts on it ({how})" + (f": {last}" if last else ""))
        out = json.loads(answer.read_text(encoding="utf-8"))
    if "refused" in out:
        raise Refused(out["refused"])
    return out


def peer_run(peer, system, dt, steps, refs, start_time=0.0):
    """{ref: np.array of values at the grid points t0 + k dt, k = 0 .. steps} of the peer's run of the
    system (an .ssd, an SSP folder or an .fmu), in a child process; refs: [(ref, instance, variable)].
    Refused says why it has none."""
    out = in_child("wavecosim.bench.peers", {"peer": peer, "system": str(system), "dt": dt, "steps": steps,
                                             "refs": list(refs), "start_time": start_time}, TITLES[peer])
    return {ref: np.array(values, dtype=float) for ref, values in out["values"].items()}


def agreement(ours, theirs):
    """{column: max |Δy| / the column's scale in the peer's run} over the common rows of two
    {column: values} (rows from the start time on; a run that ended early has fewer)."""
    out = {}
    for column in sorted(set(ours) & set(theirs)):
        a, b = np.asarray(ours[column], float), np.asarray(theirs[column], float)
        n = min(len(a), len(b))
        if not n:
            continue
        a, b = a[:n], b[:n]
        scale = column_scales(np.array([b.min()]), np.array([b.max()]), np.array([np.abs(b).max()]))[0]
        out[column] = float(np.max(np.abs(a - b)) / scale)
    return out


def quiet(message):
    """Set-up notes are not what a comparison reports."""


def ours(scenario):
    """{SUBSYSTEM.variable: values at the grid points} of the Real columns wavecosim's explicit master
    records for the scenario (no reference, no certificates)."""
    from ..run.runner import run
    from ..errors import RunFailed
    try:
        result = run(scenario.with_master(algorithm="explicit"), certificates=False, warn=quiet)
    except RunFailed as exc:             # an FMU that ended the run early: the rows it made
        result = exc.result
    traj = result.trajectory
    return {scenario.outputs.get(c, c): traj[c] for c in traj.dtype.names[1:] if traj[c].dtype.kind == "f"}


def compare(scenario, system, peer):
    """{SUBSYSTEM.variable: max |Δy| / scale} of every Real column wavecosim's explicit run of the
    scenario and the peer's run of `system` (the file it was read from) share; Refused where the
    peer cannot run the file or shares no column."""
    mine = ours(scenario)
    if not mine:
        raise Refused("nothing to compare: wavecosim records no Real output of it")
    names = sorted((s.name for s in scenario.subsystems + scenario.signal_subsystems), key=len, reverse=True)
    refs = [_split(ref, names) for ref in mine]
    theirs = peer_run(peer, system, scenario.dt, scenario.n_steps, [r for r in refs if r], scenario.start_time)
    errors = agreement(mine, theirs)
    if not errors:
        raise Refused(f"{TITLES[peer]} reads none of the {len(mine)} Real columns wavecosim records")
    return errors


def _split(ref, names):
    """(ref, instance, variable) of SUBSYSTEM.variable, the longest subsystem name that prefixes it
    (names and variables may hold dots); None for a column of no subsystem."""
    name = next((n for n in names if ref.startswith(n + ".")), None)
    return (ref, name, ref[len(name) + 1:]) if name else None


STEPS = 200                  # macro-steps of each comparison (libcosim's runs of real systems are slow-ish)
FALLBACK = {"dt": 0.01, "T": 1.0}      # an FMU without a DefaultExperiment step: dt, and T after its start


def corpus(third_party, scenes=()):
    """[(name, path)] of every system: each SSP system under third_party (a folder holding
    SystemStructure.ssd), each FMU there outside such a folder, and the in-repo `scenes` (.ssd)."""
    third_party = Path(third_party)
    folders = sorted(p.parent for p in third_party.rglob("SystemStructure.ssd"))
    fmus = sorted(p for p in third_party.rglob("*.fmu") if not any(f in p.parents for f in folders))
    return ([(str(f.relative_to(third_party)), f / "SystemStructure.ssd") for f in folders]
            + [(str(p.relative_to(third_party)), p) for p in fmus] + [(Path(s).name, Path(s)) for s in scenes])


def load_system(path, steps=STEPS):
    """The scenario wavecosim reads from the file alone, an FMU whose DefaultExperiment gives no step
    with FALLBACK (as one runs it), cut to at most `steps` macro-steps; ConfigError where wavecosim
    refuses the file."""
    from ..scenario.fmu import is_fmu, load_fmu
    from ..scenario.ssp import load_ssp
    if is_fmu(path):
        from fmpy import read_model_description
        experiment = read_model_description(str(path), validate=False).defaultExperiment
        times = {}
        if experiment is None or experiment.stepSize is None:
            start = float(experiment.startTime) if experiment is not None and experiment.startTime else 0.0
            times = {"dt": FALLBACK["dt"], "T": start + FALLBACK["T"]}
        scenario = load_fmu(path, None, times, quiet)
    else:
        scenario = load_ssp(path)[0]
    if scenario.n_steps > steps:
        scenario = scenario.with_changes(T=scenario.start_time + steps * scenario.dt)
    return scenario


def declared_tolerances(scenario):
    """{subsystem: the tolerance wavecosim gives its FMU's set-up} where there is one."""
    from fmpy import read_model_description
    out = {}
    for s in scenario.subsystems + scenario.signal_subsystems:
        tol = getattr(s, "tolerance", None)
        if tol is None and getattr(s, "fmu_path", None):
            experiment = read_model_description(str(s.fmu_path), validate=False).defaultExperiment
            tol = float(experiment.tolerance) if experiment is not None and experiment.tolerance else None
        if tol is not None:
            out[s.name] = tol
    return out


def known_deviation(peer, path, scenario):
    """(why, bound): why the peer's numbers may differ from wavecosim's on this system and the largest
    max |Δy| / range that reason explains (None, AGREE: none; they must agree)."""
    text = Path(path).read_text(errors="replace") if Path(path).suffix == ".ssd" else ""
    if peer == "libcosim" and re.search(r"<\w+:ParameterMapping\b", text):
        return "libcosim ignores the system's .ssm parameter mapping (its parameters keep their start values)", math.inf
    tolerances = declared_tolerances(scenario)
    if peer == "fmpy" and scenario.start_time != 0.0:
        return (f"fmpy's simulate_fmu steps by t_n+1 - t_n from the start time {scenario.start_time:g}, which is "
                "not dt to the last bit, and the FMU's internal fixed-step solver follows it (wavecosim equals "
                "a plain loop of doStep(t_n, dt))", TOLERANCE_SPREAD * max([AGREE, *tolerances.values()]))
    if peer != "fmpy" and tolerances:
        return (f"the FMUs' DefaultExperiment tolerance ({', '.join(f'{k} {v:g}' for k, v in tolerances.items())}), "
                f"which wavecosim passes to their set-up and {TITLES[peer]} does not",
                TOLERANCE_SPREAD * max(tolerances.values()))
    return None, AGREE


def verdict(peer, path, scenario, errors):
    """(agrees, words): whether every common column agrees to AGREE or the difference has a known
    reason (known_deviation), and what the table says."""
    worst = max(errors.values())
    column = max(errors, key=errors.get)
    said = f"{len(errors)} column{'s' if len(errors) != 1 else ''}, largest Δ/range {worst:.1e}"
    if worst <= AGREE:
        return True, f"agrees ({said})"
    reason, bound = known_deviation(peer, path, scenario)
    if reason is None or not worst <= bound:
        return False, f"DIFFERS ({said}, worst {column})" + (f", more than {reason} explains" if reason else "")
    return True, f"differs as expected ({said}, worst {column}): {reason}"
