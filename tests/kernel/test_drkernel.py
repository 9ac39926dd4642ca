"""The DR kernel's own parts (kernel/drkernel.py, kernel/c/drkernel.c): the thread plan and what it
changes (no number), an FMU error on the worker thread, the deadline.
Its numbers against the Python reference: tests/masters/test_routes.py.
"""
import copy
import dataclasses

import pytest

from paths import ROOT
from wavecosim.scenario.config import load_scenario
from wavecosim.errors import FmuError
from wavecosim.kernel.drkernel import thread_plan
from wavecosim.masters.dr_fast import FastDRMaster
from wavecosim.run.runner import run
from wavecosim.core.scene import build_scene


@pytest.fixture(scope="module")
def table_i(built_fmus):
    return load_scenario()


def test_auto_threads_stays_serial_for_light_fmus(table_i):
    scene = build_scene(table_i)
    master = FastDRMaster(scene, dataclasses.replace(table_i.master, K=8, fast="true", threads="auto"))
    try:
        for n in range(3):
            master.step(n, n * table_i.dt)
        assert master.threads == 1 and master.thread_note.startswith("serial"), master.thread_note
        assert all(c > 0 for c in master.costs_us)
    finally:
        master.close()
        scene.close()


def test_thread_plan_balances_cost():
    plan, load = thread_plan([300.0, 1.0, 280.0], 2)
    assert plan[0] != plan[2] and sorted(load) == [281.0, 300.0]


def test_an_fmu_error_on_the_worker_thread_names_its_subsystem(table_i):
    """The Duffing side's doStep fails at step 18 (its Newton held to 4 iterations at q1 = 2) while it
    runs on the kernel's worker thread: its log comes from there, named as the reference names it."""
    scenario = dataclasses.replace(copy.deepcopy(table_i), T=1.0)
    scenario.subsystems[0].integers["newton_max_iter"] = 4
    scenario.subsystems[0].start["q1"] = 2.0
    scene = build_scene(scenario)
    master = FastDRMaster(scene, dataclasses.replace(scenario.master, K=3, fast="true", threads="1"))
    assert master.kernel.set_threads([1, 0])        # A on the worker thread
    try:
        with pytest.raises(FmuError) as info:
            for n in range(scenario.n_steps):
                master.step(n, n * scenario.dt)
        assert str(info.value).startswith("subsystem A: fmi2DoStep returned Error at step 18 (t = 0.18)")
        assert "Newton step of the Duffing side did not converge" in str(info.value)
        assert (info.value.subsystem, info.value.step) == ("A", 18)
    finally:
        master.close()
        scene.close()


def test_deadline_stops_the_inner_loop(table_i):
    scenario = dataclasses.replace(table_i, T=0.5).with_master(K=100000, deadline_us=200.0, fast="true")
    result = run(scenario, certificates=False)
    assert result.summary["fast_path"] is True and result.summary["threads"] == 1
    assert 0 < max(result.steps["iterations"]) < 100000


def test_heavy_scene_threads_auto(built_fmus):
    """configs/heavy_chain.yaml: the chains cost well over PARALLEL_MIN_US per evaluation, so auto
    tries two threads (and keeps them unless the machine is too busy); same numbers as serial."""
    if "HeavyChain" not in built_fmus:
        pytest.skip("the HeavyChain FMU is not available")
    scenario = dataclasses.replace(load_scenario(ROOT / "configs" / "heavy_chain.yaml"), T=0.05)
    serial = run(scenario.with_master(fast="true", threads="1"), certificates=False)
    auto = run(scenario.with_master(fast="true", threads="auto"), certificates=False)
    assert serial.trajectory.tobytes() == auto.trajectory.tobytes()
    assert serial.steps.tobytes() == auto.steps.tobytes()
    note = auto.summary["thread_note"]
    assert note.startswith("2 threads") or note.startswith("serial: 2 threads were not faster"), note
