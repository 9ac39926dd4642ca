"""Initialization to consistency: in initialization mode every input an FMU output drives is set
from that output in dependency order, sweep after sweep, until nothing changes, so the first row of
a run equals what an FMPy loop reports when it repeats the propagation until nothing changes. On
Gain FMUs (y = k u + c, direct feed-through): a three-FMU chain, a loop that settles, a loop that
does not (solved by a damped Newton, with a warning) and one without a solution (refused in one
line naming its connections)."""
import struct

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from paths import THIRD_PARTY

import wavecosim as wc
from wavecosim.errors import NumericalError
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

OMS = THIRD_PARTY / "omsimulator"
CHAIN = {
    "name": "chain", "dt": 0.1, "T": 0.3,
    "subsystems": {"A": {"fmu": "Gain", "parameters": {"k": 2.0, "c": 1.0}, "start": {"u": 1.5}},
                   "B": {"fmu": "Gain", "parameters": {"k": -3.0, "c": 0.5}},
                   "C": {"fmu": "Gain", "parameters": {"k": 0.25, "c": -2.0}}},
    "signals": [{"from": "B.y", "to": "C.u", "factor": 2.0, "offset": 0.125},
                {"from": "A.y", "to": "B.u"}],
}
# A.y -> B.u, B.y -> C.u, C.y -> A.u: y_A = 0.5 u_A + 1, y_B = 2 u_B, y_C = 3 whatever u_C, so the
# loop has one fixed point (u_A = 3.5) that propagation reaches after a few passes
LOOP = {
    "name": "loop", "dt": 0.1, "T": 0.3,
    "subsystems": {"A": {"fmu": "Gain", "parameters": {"k": 0.5, "c": 1.0}},
                   "B": {"fmu": "Gain", "parameters": {"k": 2.0}},
                   "C": {"fmu": "Gain", "parameters": {"k": 0.0, "c": 3.0}}},
    "signals": [{"from": "A.y", "to": "B.u"}, {"from": "B.y", "to": "C.u"}, {"from": "C.y", "to": "A.u", "offset": 0.5}],
}


def _bits(values):
    return [struct.pack("<d", v) for v in values]


def fmpy_start(path, tmp_path, raw):
    """An FMPy loop over the scenario's Gain FMUs: instantiate, set up, parameters, enter
    initialization mode, then get every source and set every input (factor and offset applied)
    until a pass changes nothing, exit; {SUB.y: value} read at the start time."""
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(path), unzipdir=str(tmp_path / "gain"))
    fmus = {}
    for name, sub in raw["subsystems"].items():
        fmu = fmus[name] = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="Gain", instanceName=name)
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        values = {**sub.get("parameters", {}), **sub.get("start", {})}
        fmu.setReal([vr[k] for k in values], list(values.values()))
        fmu.enterInitializationMode()
    before = None
    while True:
        for sig in raw["signals"]:
            (src, out), (dst, inp) = sig["from"].split("."), sig["to"].split(".")
            y = fmus[src].getReal([vr[out]])[0]
            fmus[dst].setReal([vr[inp]], [sig.get("factor", 1.0) * y + sig.get("offset", 0.0)])
        now = _bits(fmus[name].getReal([vr["y"]])[0] for name in fmus)
        if now == before:
            break
        before = now
    for fmu in fmus.values():
        fmu.exitInitializationMode()
    out = {f"{name}.y": fmu.getReal([vr["y"]])[0] for name, fmu in fmus.items()}
    for fmu in fmus.values():
        fmu.terminate()
        fmu.freeInstance()
    return out


def first_row(raw):
    result = run(parse_scenario(raw, f"{raw['name']}.yaml"))
    return {col: float(result.trajectory[col][0]) for col in result.trajectory.dtype.names}


def test_gain_validates(built_fmus):
    assert validate_fmu(str(built_fmus["Gain"])) == []


@pytest.mark.parametrize("raw", [CHAIN, LOOP], ids=["chain", "loop"])
def test_first_row_is_the_settled_start(built_fmus, tmp_path, raw):
    expected = fmpy_start(built_fmus["Gain"], tmp_path, raw)
    row = first_row(raw)
    assert _bits(row[c] for c in expected) == _bits(expected.values())


def test_settled_values(built_fmus):
    """The chain's signals are listed against the flow (B.y -> C.u first): one pass in the file's
    order would leave C at its start; the loop starts away from its fixed point."""
    row = first_row(CHAIN)
    y_a = 2.0 * 1.5 + 1.0
    y_b = -3.0 * y_a + 0.5
    assert (row["A.y"], row["B.y"], row["C.y"]) == (y_a, y_b, 0.25 * (2.0 * y_b + 0.125) - 2.0)
    row = first_row(LOOP)
    assert (row["A.u"], row["A.y"], row["B.y"], row["C.y"]) == (3.5, 2.75, 5.5, 3.0)


def test_a_loop_that_does_not_settle_is_solved_by_newton_with_a_warning(built_fmus):
    """Loop gain 0.5 * 2 * 3 = 3: propagation runs away, the loop's one solution is u_A = -3.25."""
    raw = {**LOOP, "subsystems": {**LOOP["subsystems"], "C": {"fmu": "Gain", "parameters": {"k": 3.0}}}}
    notes = []
    result = wc.simulate(parse_scenario(raw, "loop.yaml"), warn=notes.append)
    row = {c: float(result.trajectory[c][0]) for c in ("A.u", "A.y", "B.y", "C.y")}
    assert row == pytest.approx({"A.u": -3.25, "A.y": -0.625, "B.y": -1.25, "C.y": -3.75}, rel=1e-12, abs=1e-12)
    said = [n for n in notes if "algebraic loop" in n]
    assert len(said) == 1 and "solved by a damped Newton" in said[0]
    assert all(f"{a}.y -> {b}.u" in said[0] for a, b in ("AB", "BC", "CA"))


def test_a_loop_without_a_solution_is_refused_in_one_line(built_fmus):
    """y_A = u_A + 1 fed back through y_B = u_B: u = u + 1 has no solution."""
    raw = {**LOOP, "subsystems": {"A": {"fmu": "Gain", "parameters": {"c": 1.0}}, "B": {"fmu": "Gain"}},
           "signals": [{"from": "A.y", "to": "B.u"}, {"from": "B.y", "to": "A.u"}]}
    with pytest.raises(NumericalError) as err:
        run(parse_scenario(raw, "loop.yaml"))
    text = str(err.value)
    assert "\n" not in text and "finds no solution" in text and "A.y -> B.u" in text and "B.y -> A.u" in text


def test_settled_run_keeps_going(built_fmus):
    """After the settled start the run steps on: x integrates y, constant here."""
    result = run(parse_scenario(CHAIN, "chain.yaml"))
    assert np.all(result.trajectory["C.y"] == result.trajectory["C.y"][0])
    assert result.trajectory["A.x"][-1] == pytest.approx(0.3 * 4.0)


def assert_consistent_start(scenario, result):
    """Every Real signal between two recorded columns holds at the first row: to = factor from + offset."""
    traj, checked = result.trajectory, 0
    for sig in scenario.signals:
        if sig.source in traj.dtype.names and sig.target in traj.dtype.names and traj[sig.target].dtype.kind == "f":
            assert traj[sig.target][0] == sig.factor * traj[sig.source][0] + sig.offset, sig
            checked += 1
    assert checked


def test_the_chain_and_linear_transformation3_start_consistent(built_fmus):
    assert_consistent_start(parse_scenario(CHAIN, "chain.yaml"), run(parse_scenario(CHAIN, "chain.yaml")))
    folder = OMS / "LinearTransformation3"
    if not folder.exists():
        pytest.skip("the third-party systems (../shared/third_party) are absent")
    scenario = wc.load(folder / "SystemStructure.ssd", warn=lambda message: None)
    result = wc.simulate(scenario, warn=lambda message: None)
    assert result.trajectory["Gain1.y"][0] == result.trajectory["Add1.u1"][0] == 182.0    # OMSimulator's k u
    assert_consistent_start(scenario, result)


@pytest.mark.slow
def test_embrace_starts_consistent_through_its_adaption_unit():
    """ECS_HW.LHexTout -> AdaptionUnit (feed-through) -> ECS_SW.Input.TLiquid: 273 K from the first row."""
    path = OMS / "embrace" / "SystemStructure.ssd"
    if not path.exists():
        pytest.skip("the third-party systems (../shared/third_party) are absent")
    scenario = wc.load(path, T=0.005, warn=lambda message: None)
    result = wc.simulate(scenario, warn=lambda message: None)
    assert result.trajectory["ECS_SW.Input.TLiquid"][0] == result.trajectory["AdaptionUnit.sWsignals.TLiquid"][0]
    assert_consistent_start(scenario, result)
