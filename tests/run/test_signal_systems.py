"""Systems without power bonds: subsystems joined by signals only (or one FMU alone) run on the
explicit master, with no gamma, no probes, no monolithic reference and no certificates, and give
what a plain fmpy loop gives (doStep(t_n, dt), each input set from the other FMU's output at t_n),
to the last bit."""
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from wavecosim.errors import ConfigError
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

DT, T = 0.01, 0.3
PAIR = {
    "name": "pair", "dt": DT, "T": T,
    "subsystems": {"A": {"fmu": "LinearSide", "parameters": {"m2": 1.0, "k2": 10.0}, "start": {"q2": 0.1}},
                   "B": {"fmu": "LinearSide", "parameters": {"m2": 2.0, "k2": 5.0}}},
    "signals": [{"from": "A.q2", "to": "B.F", "factor": 3.0}, {"from": "B.q2", "to": "A.F", "offset": 0.5}],
    "outputs": {"qA": "A.q2", "qB": "B.q2"},
}


def pair(**changes):
    return parse_scenario({**PAIR, **changes}, "pair.yaml")


def plain_loop(built_fmus, tmp_path):
    """Both LinearSides stepped by fmpy: at each t_n both outputs read, both inputs set, both doSteps."""
    path = built_fmus["LinearSide"]
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    folder = extract(str(path), unzipdir=str(tmp_path / "ls"))
    fmus = {}
    for name, values in (("A", {"m2": 1.0, "k2": 10.0, "q2": 0.1}), ("B", {"m2": 2.0, "k2": 5.0})):
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier="LinearSide", instanceName=name)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([vr[k] for k in values], list(values.values()))
        fmu.setInteger([vr["port_mode"]], [1])          # a LinearSide without a port takes its force F
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmus[name] = fmu
    rows = []
    for n in range(round(T / DT) + 1):
        qa, qb = fmus["A"].getReal([vr["q2"]])[0], fmus["B"].getReal([vr["q2"]])[0]
        rows.append((qa, qb))
        if n == round(T / DT):
            break
        fmus["B"].setReal([vr["F"]], [3.0 * qa + 0.0])
        fmus["A"].setReal([vr["F"]], [1.0 * qb + 0.5])
        for fmu in fmus.values():
            fmu.doStep(n * DT, DT)
    for fmu in fmus.values():
        fmu.terminate()
        fmu.freeInstance()
    return np.array(rows)


def test_a_pair_joined_by_signals_runs_on_the_explicit_master_as_a_plain_loop(built_fmus, tmp_path):
    sc = pair()
    assert sc.master.algorithm == "explicit" and sc.gamma is None and sc.couplings == []
    assert [s.name for s in sc.signal_subsystems] == ["A", "B"] and sc.subsystems == []
    result = run(sc)
    expected = plain_loop(built_fmus, tmp_path)
    assert np.array_equal(result.trajectory["qA"], expected[:, 0])
    assert np.array_equal(result.trajectory["qB"], expected[:, 1])
    assert result.reference is None and result.steps.dtype.names == ("time", "iterations", "inner_residual", "reason")
    assert not any(k.startswith(("gamma", "max_passivity", "max_augmented", "energy")) for k in result.summary
                   if k != "energy_guard")


def test_an_iterating_master_is_refused_without_power_bonds():
    with pytest.raises(ConfigError, match="pair.yaml: master.algorithm: dr couples power bonds, and this system "
                                          "has none"):
        pair(master={"algorithm": "dr"})
    with pytest.raises(ConfigError, match="--master: newton couples power bonds"):
        from wavecosim.api import with_overrides
        with_overrides(pair(), master="newton", where="--T/--dt")
