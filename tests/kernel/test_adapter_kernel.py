"""The wave adapter in C (kernel/c/adapter.c, wavecosim/core/adapter_kernel.py): the DR kernel runs
subsystems with physical ports through the adapter's fmi2 shim, bit-identical to the Python
reference (wavecosim/core/ports.py::WaveAdapter): trajectories, steps tables, doSteps per frozen-map
evaluation and FMU call counts; a failed query gives the same error line; two-channel ports
(Gauss-Jordan inverse, Broyden updates, stalled queries) give the same numbers query by query."""
import copy

import numpy as np
import pytest

from paths import ROOT
from wavecosim.kernel import linalg
from wavecosim.core import ports
from wavecosim.scenario.config import load_scenario, parse_scenario
from wavecosim.errors import FmuError, NumericalError, RunFailed
from wavecosim.kernel.drkernel import adapter_port, fmu_functions
from wavecosim.core.adapter_kernel import KernelAdapter
from wavecosim.run.runner import run
from wavecosim.core.scene import build_scene

PAIR = ROOT / "configs" / "foreign_pair.yaml"
DCMOTOR = ROOT / "configs" / "dcmotor_shaft.yaml"
THIRD_PARTY = ROOT.parent / "shared" / "third_party" / "dcmotor"


def quiet(msg):
    """Set-up notes are not under test here."""


@pytest.fixture(scope="module")
def pair():
    return load_scenario(PAIR).with_changes(T=0.2)


def both_routes(scenario, **options):
    """The run through the C kernel (fast: true insists on it) and through the Python reference."""
    return [run(scenario.with_master(fast=fast), warn=quiet, **options) for fast in ("true", "false")]


def assert_same_run(kernel, python):
    assert kernel.summary["fast_path"] and kernel.summary["fast_note"] == "C kernel"
    assert not python.summary["fast_path"]
    assert kernel.trajectory.tobytes() == python.trajectory.tobytes()
    assert kernel.steps.tobytes() == python.steps.tobytes()
    for key in ("wave_adapter", "fmu_calls", "iterations_mean", "port_signs"):
        assert kernel.summary[key] == python.summary[key], key


@pytest.mark.parametrize("K", [0, 5, 50])
def test_the_kernel_route_is_the_python_route_to_the_last_bit(pair, K):
    kernel, python = both_routes(pair.with_master(K=K))
    assert_same_run(kernel, python)
    per_evaluation = [info["doSteps_per_evaluation"] for info in kernel.summary["wave_adapter"].values()]
    assert all(1.0 < x < 3.0 for x in per_evaluation)


def test_two_threads_change_no_number(pair):
    kernel, python = both_routes(pair.with_master(K=5, threads="2"))
    assert kernel.summary["threads"] == 2
    assert_same_run(kernel, python)


def test_dr_on_the_kernel_route_meets_the_monolithic_reference(pair):
    """K = 50 at gamma auto through the C adapter: the error is at roundoff, as on the Python route."""
    result = run(pair.with_master(fast="true"), reference="lockstep", warn=quiet)
    assert result.summary["fast_path"] and result.summary["max_error"] <= 1e-9


@pytest.mark.skipif(not THIRD_PARTY.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_the_dcmotor_shaft_is_the_same_on_both_routes():
    """Dymola FMUs whose step map is smooth only to their solver's tolerance: some queries stall
    and keep their best point (the accept path), in C as in Python."""
    kernel, python = both_routes(load_scenario(DCMOTOR))
    assert_same_run(kernel, python)
    assert kernel.summary["wave_adapter"]["machine"]["stalled_queries"] > 0


def test_an_unsolved_query_fails_with_the_same_line_on_both_routes(pair, monkeypatch):
    monkeypatch.setattr(ports, "TOL", 0.0)
    monkeypatch.setattr(ports, "ACCEPT", 0.0)
    errors = []
    for fast in ("true", "false"):
        with pytest.raises(RunFailed) as failed:
            run(pair.with_changes(gamma=1.0).with_master(fast=fast), warn=quiet)
        assert isinstance(failed.value.error, NumericalError)
        errors.append(str(failed.value.error))
    assert errors[0] == errors[1]
    assert errors[0].startswith("subsystem A: wave adapter at step 0 (t = 0): no convergence in 30 Newton iterations")


def test_an_fmu_error_inside_a_query_is_the_same_on_both_routes(pair):
    """A spring so stiff that one doStep overflows its force: the FMU's own error, named as the
    Python route names it (the call inside the adapter, not the kernel's call of the adapter)."""
    stiff = copy.deepcopy(pair.with_changes(gamma=1.0))
    stiff.subsystems[1].parameters["k"] = 1e300
    errors = []
    for fast in ("true", "false"):
        with pytest.raises(RunFailed) as failed:
            run(stiff.with_master(fast=fast, K=5), warn=quiet)
        assert isinstance(failed.value.error, FmuError)
        errors.append(str(failed.value.error))
    assert errors[0] == errors[1]
    assert errors[0].startswith("subsystem B: fmi2DoStep returned Error at step 0 (t = 0)")


def chain_pair():
    """Two ChainLinks in their physical port mode: a two-channel physical port each (effort in on the
    left, flow in on the right)."""
    port = {"physical_in": ["F_left", "u_right"], "physical_out": ["f_left", "e_right"], "input": ["effort", "flow"],
            "energy": "H"}
    link = {"fmu": "ChainLink", "parameters": {"m": 1.0, "k": 100.0, "c": 0.05}, "port": port}
    raw = {"dt": 0.01, "T": 0.1, "gamma": 0.4,
           "subsystems": {"L0": {**link, "start": {"q": 0.0, "v": 1.0, "d": 0.0}},
                          "L1": {**link, "start": {"q": 0.0, "v": 0.0, "d": 0.0}}},
           "couplings": [{"type": "free_end", "ports": ["L0[0]"]},
                         {"type": "equal_effort_opposite_flow", "ports": ["L0[1]", "L1[0]"]},
                         {"type": "clamped_end", "ports": ["L1[1]"]}]}
    return parse_scenario(raw, "chain_pair.yaml", ROOT / "configs")


def adapted(scene, in_c):
    """The scene's first link with a wave adapter over its physical port, in Python or in C."""
    sub = scene.subsystems[0]
    sub.adapter = True
    sub.map = ports.WaveAdapter(sub, [not flow_in for flow_in in sub.port.input_is_flow], sub.port.sign, 0.4)
    if in_c:
        adapter_port(sub, *fmu_functions(sub))
        assert isinstance(sub.map, KernelAdapter)
    return sub


def drive(sub, steps=8, queries=4):
    """Macro-steps of a few queries at scattered incident waves and one commit; all outputs."""
    rng, out = np.random.default_rng(7), []
    for n in range(steps):
        sub.freeze(n, n * sub.dt)
        for _ in range(queries):
            out.append(sub.query(list(rng.normal(0.0, 0.5, 2))))
        out.append(sub.advance(list(rng.normal(0.0, 0.5, 2))))
    return np.asarray(out).tobytes(), sub.map.info(), dict(sub.calls)


@pytest.mark.parametrize("tol, accept", [(ports.TOL, ports.ACCEPT), (0.0, 1e-2)])
def test_a_two_channel_port_gives_the_same_queries_in_c(tol, accept, monkeypatch):
    """Query by query on two identical instances; with TOL = 0 a query not solved exactly runs
    Broyden updates until it stalls and keeps its best point."""
    monkeypatch.setattr(ports, "TOL", tol)
    monkeypatch.setattr(ports, "ACCEPT", accept)
    results = []
    for in_c in (False, True):
        scene = build_scene(chain_pair(), wave=False)
        try:
            results.append(drive(adapted(scene, in_c)))
        finally:
            scene.close()
    assert results[0] == results[1]
    info = results[0][1]
    assert info["map_evaluations"] == 40
    assert (info["stalled_queries"] > 0) == (tol == 0.0)


def test_the_inverse_is_lapacks_for_one_channel_and_pivots():
    for x in (3.0, -0.1, 7e-300, 1.0 / 3.0):
        assert linalg.inverse([[x]])[0][0] == np.linalg.inv([[x]])[0][0]
    M = [[0.0, 2.0, 1.0], [1.0, 1e-3, 0.0], [4.0, 1.0, 3.0]]           # a zero leading pivot
    np.testing.assert_allclose(linalg.inverse(M), np.linalg.inv(M), rtol=1e-12, atol=1e-14)
    assert all(np.isnan(x) for row in linalg.inverse([[1.0, 2.0], [2.0, 4.0]]) for x in row)
