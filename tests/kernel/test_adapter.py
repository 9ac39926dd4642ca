"""The wave adapter's solve in C (kernel/c/adapter.c, wavecosim/core/adapter_kernel.py) answers every
query as the Python reference (wavecosim/core/ports.py::WaveAdapter), to the last bit, on a two-channel
port (Gauss-Jordan inverse, Broyden updates, stalled queries): outputs, figures and FMU calls. Whole
runs through the adapter on both routes: tests/masters/test_routes.py."""
import numpy as np
import pytest

from paths import ROOT
from wavecosim.core import ports
from wavecosim.core.adapter_kernel import KernelAdapter
from wavecosim.core.scene import build_scene
from wavecosim.core.kernel_scene import kernel_subsystem
from wavecosim.scenario.config import parse_scenario


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
        kernel_subsystem(sub, 0)
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
