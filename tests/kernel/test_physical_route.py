"""Physical ports, signals, sources and subsystems stepped alone on the kernel route.

Claims: every master runs the in-repo foreign pair (physical ports with signs; DR through the wave
adapter, with the energy ledger kept in the kernel) and the dcmotor system (signals from a
subsystem stepped alone and from a port subsystem, physical ports, when ../shared is there) in
blocks of macro-steps per kernel call (`fast_path: true`, every step in a block), and the
trajectories, per-step logs and FMU call counts equal the Python reference's (`fast: false`) bit
for bit; a scene with a source table and a subsystem stepped alone does too, for a physical and a
wave master; Integer and Boolean signals (FMI 2) too; systems of signals alone (the in-repo signal
pair, OMSimulator's LinearTransformation SSD) run on the explicit master in blocks, bit for bit; a non-finite signal inside a block fails as the
reference does, after the same rows.
"""
import copy
import dataclasses

import numpy as np
import pytest

from paths import CONFIGS, THIRD_PARTY
from scenes import SIGNAL_SCENE
from wavecosim.errors import RunFailed
from wavecosim.bench.real_fmus import signal_pair
from wavecosim.run.runner import LiveRun, _loop, run
from wavecosim.scenario.config import load_scenario, parse_scenario
from wavecosim.scenario.ssp import load_ssp

MASTERS = ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "dr")


def quiet(message):
    """Set-up notes are not under test here."""


def both_routes(sc, **kw):
    """The run on the kernel route (auto) and on the Python reference (false)."""
    return [run(sc.with_master(fast=fast), warn=quiet, certificates=False, **kw) for fast in ("auto", "false")]


def identical(fast, ref, steps):
    assert fast.summary["fast_path"] is True and ref.summary["fast_path"] is False
    assert fast.summary["block_steps"] == steps and ref.summary["block_steps"] == 0
    assert fast.status == ref.status
    for name in ("trajectory_table", "steps_table"):
        a, b = getattr(fast, name).array(), getattr(ref, name).array()
        assert a.tobytes() == b.tobytes(), name
    assert fast.summary["fmu_calls"] == ref.summary["fmu_calls"]


@pytest.mark.parametrize("master", MASTERS)
def test_the_foreign_pair_runs_in_blocks_bit_for_bit(master, built_fmus):
    sc = dataclasses.replace(load_scenario(CONFIGS / "foreign_pair.yaml"), T=0.3).with_master(algorithm=master, K=5)
    fast, ref = both_routes(sc)
    identical(fast, ref, sc.n_steps)
    if master == "dr":
        assert fast.summary["energy_guard"] == "ledger"


@pytest.mark.skipif(not (THIRD_PARTY / "dcmotor").is_dir(), reason="../shared/third_party is not here")
@pytest.mark.parametrize("master", ["explicit", pytest.param("jacobi-iter", marks=pytest.mark.slow),
                                    pytest.param("dr", marks=pytest.mark.slow)])
def test_the_dcmotor_runs_in_blocks_bit_for_bit(master):
    sc = dataclasses.replace(load_scenario(CONFIGS / "dcmotor.yaml"), T=0.2).with_master(algorithm=master, K=5,
                                                                                          threads=1)
    fast, ref = both_routes(sc)            # threads=1: no step on trial of two threads outside the blocks
    identical(fast, ref, sc.n_steps)
    assert fast.summary["signals"] == 3


SIGNALS = {
    **SIGNAL_SCENE,
    "sources": {"push": {"csv": "push.csv", "interpolation": "linear"}},
    "signals": [{"from": "push.force", "to": "B.F_right", "factor": 3.0, "offset": -0.25},
                {"from": "A.q1", "to": "S.F", "factor": 2.0, "offset": 0.5}],
    "master": {"algorithm": "explicit", "K": 4},
    "outputs": {"q1": "A.q1", "q": "B.q", "held": "B.F_right", "F_S": "S.F", "q_S": "S.q2"},
}


def signal_scene(folder, master, table="time,force\n0.0,0.0\n0.05,1.0\n0.13,-2.0\n1.0,1.0\n", how="linear"):
    (folder / "push.csv").write_text(table)
    raw = copy.deepcopy(SIGNALS)
    raw["master"]["algorithm"] = master
    raw["sources"]["push"]["interpolation"] = how
    if master in ("dr", "newton"):
        raw["signals"][0]["to"] = raw["outputs"]["held"] = "B.a_right"
    return parse_scenario(raw, "signals.yaml", folder)


@pytest.mark.parametrize("master", ["explicit", "gauss-seidel-iter", "dr"])
def test_signals_from_a_table_and_a_subsystem_stepped_alone_in_blocks(tmp_path, master, built_fmus):
    sc = signal_scene(tmp_path, master)
    fast, ref = both_routes(sc, output_interval=3)
    identical(fast, ref, sc.n_steps)
    held = fast.trajectory["held"]
    assert len(set(held.tolist())) > 5 and np.any(fast.trajectory["q_S"] != 0.0)


def test_a_non_finite_signal_fails_in_a_block_as_in_python(tmp_path, built_fmus):
    sc = signal_scene(tmp_path, "jacobi-iter", "time,force\n0.0,0.0\n0.07,1e308\n", "hold")
    failed = []
    for fast in ("auto", "false"):
        with pytest.raises(RunFailed) as info:
            run(sc.with_master(fast=fast), warn=quiet, certificates=False)
        failed.append(info.value)
    assert str(failed[0]) == str(failed[1]) and "signals[0]: push.force gave inf at step 7" in str(failed[0])
    assert failed[0].result.summary["block_steps"] == 7
    for name in ("trajectory_table", "steps_table"):
        assert getattr(failed[0].result, name).array().tobytes() == getattr(failed[1].result, name).array().tobytes()


TYPED = {
    "name": "typed", "dt": 0.05, "T": 2.0,
    "subsystems": {"src": {"fmu": "SignalSource", "parameters": {"frequency": 0.5}, "integers": {"period": 3}},
                   "sink": {"fmu": "SignalSink", "parameters": {"gain": 3.0}},
                   "sink2": {"fmu": "SignalSink", "parameters": {"gain": 2.0}}},
    "signals": [{"from": "src.count", "to": "sink.u", "factor": 2.0, "offset": 0.25},    # Integer -> Real
                {"from": "src.count", "to": "sink.n"},                                 # Integer -> Integer
                {"from": "src.flag", "to": "sink.on"},                                 # Boolean -> Boolean
                {"from": "src.flag", "to": "sink2.u", "factor": -1.5},                 # Boolean -> Real
                {"from": "src.flag", "to": "sink2.n"}],                                # Boolean -> Integer
    "outputs": {"i": "sink.integral", "s": "sink.scaled", "i2": "sink2.integral", "y": "src.y"},
}


def test_integer_and_boolean_signals_are_held_in_the_blocks(built_fmus):
    """The kernel reads and sets FMI 2 Integer and Boolean variables itself: every step in blocks, the
    Real outputs and the sinks' Integer and Boolean outputs at the end as the Python route's."""
    ends, results = [], []
    for fast in ("auto", "false"):
        live = LiveRun(parse_scenario(TYPED, "typed.yaml").with_master(fast=fast), warn=quiet, certificates=False)
        status, error = _loop(live, None, None)
        sinks = {s.name: s.fmu for s in live.scene.signal_only if s.name.startswith("sink")}
        ends.append([(f.get_values("Integer", [f.vr("shifted")])[0], f.get_values("Boolean", [f.vr("off")])[0])
                     for f in sinks.values()])
        results.append(live.finish(status, str(error or "")))
    assert results[0].summary["fast_path"] and results[0].summary["block_steps"] == 40
    assert results[1].summary["block_steps"] == 0 and ends[0] == ends[1] and ends[0][0][0] > 10
    assert results[0].trajectory_table.array().tobytes() == results[1].trajectory_table.array().tobytes()


def test_the_in_repo_signal_pair_runs_in_blocks_bit_for_bit(built_fmus):
    sc = dataclasses.replace(signal_pair(), T=0.2)
    fast, ref = both_routes(sc)
    identical(fast, ref, sc.n_steps)


@pytest.mark.skipif(not (THIRD_PARTY / "omsimulator" / "LinearTransformation").is_dir(),
                    reason="../shared/third_party is not here")
def test_a_signal_only_ssd_runs_in_blocks_bit_for_bit():
    """OMSimulator's LinearTransformation (two FMUs, one signal scaled by the SSD): explicit in blocks."""
    sc = load_ssp(THIRD_PARTY / "omsimulator" / "LinearTransformation")[0]
    fast, ref = both_routes(sc)
    identical(fast, ref, sc.n_steps)
    assert fast.summary["master"] == "explicit"
