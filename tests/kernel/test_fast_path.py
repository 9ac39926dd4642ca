"""The C fast path of the DR master gives the reference's numbers to the last bit.

Claims: over whole runs of the Table I scene, trajectories, per-step logs and FMU call counts of
`master.fast: true` equal those of the Python reference (`fast: false`) bit for bit, for several
budgets K, with and without the tolerance exit; the thread plan never changes a number; an FMU
error inside the kernel comes back as the reference's FmuError, naming subsystem, step and time.
"""
import dataclasses

import numpy as np
import pytest

from paths import ROOT
from wavecosim.scenario.config import load_scenario
from wavecosim.errors import ConfigError, FmuError
from wavecosim.kernel.drkernel import Kernel, thread_plan
from wavecosim.masters import MASTERS
from wavecosim.masters.dr import DRMaster
from wavecosim.masters.dr_fast import FastDRMaster
from wavecosim.run.runner import RunFailed, run
from wavecosim.core.scene import build_scene

T_SHORT = 3.0          # 300 macro-steps of the Table I scene


@pytest.fixture(scope="module")
def table_i(built_fmus):
    return load_scenario()


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


def runs_identical(a, b):
    assert a.status == b.status == "finished"
    assert bits(a.t) == bits(b.t)
    assert bits(a.outputs) == bits(b.outputs), "trajectories differ"
    assert a.steps.dtype == b.steps.dtype
    for key in a.steps.dtype.names:
        assert a.steps[key].tobytes() == b.steps[key].tobytes(), f"per-step {key} differs"
    assert a.summary["fmu_calls"] == b.summary["fmu_calls"]


def run_pair(scenario, certificates, **master):
    ref = run(scenario.with_master(fast="false", **master), certificates=certificates)
    fast = run(scenario.with_master(fast="true", **master), certificates=certificates)
    return ref, fast


def test_dr_uses_the_fast_path(table_i):
    assert MASTERS["dr"] is FastDRMaster
    scene = build_scene(table_i)
    try:
        on = FastDRMaster(scene, dataclasses.replace(table_i.master, fast="auto"))
        off = FastDRMaster(scene, dataclasses.replace(table_i.master, fast="false"))
        assert on.fast and on.kernel is not None
        assert not off.fast and off.kernel is None
        on.close()
        off.close()
    finally:
        scene.close()


@pytest.mark.parametrize("K", [0, 1, 3, 8, 50])
def test_whole_run_bit_identical(table_i, K):
    scenario = dataclasses.replace(table_i, T=T_SHORT)
    ref, fast = run_pair(scenario, certificates=K in (3, 8), K=K)
    runs_identical(ref, fast)
    assert ref.summary["energy_guard_steps"] == fast.summary["energy_guard_steps"]
    if ref.summary["energy_guard_steps"] == 0:
        assert list(ref.steps["iterations"]) == [K] * scenario.n_steps


def test_tolerance_exit_bit_identical(table_i):
    scenario = dataclasses.replace(table_i, T=T_SHORT)
    ref, fast = run_pair(scenario, certificates=False, K=50, eps=1e-9)
    runs_identical(ref, fast)
    assert min(ref.steps["iterations"]) < 50          # the tolerance exit was taken


@pytest.mark.parametrize("K,eps", [(0, None), (8, None), (50, 1e-9)])
def test_step_logs_bit_identical(table_i, K, eps):
    """Every field of every StepLog (iterations, residual, reason, a_hat, u^0, u^K) and the b^n."""
    settings = dataclasses.replace(table_i.master, K=K, eps=eps)
    scenes = [build_scene(table_i), build_scene(table_i)]
    ref = DRMaster(scenes[0], settings)
    fast = FastDRMaster(scenes[1], dataclasses.replace(settings, fast="true"))
    try:
        for n in range(200):
            t = n * table_i.dt
            a, b = ref.step(n, t), fast.step(n, t)
            assert (a.iterations, a.reason) == (b.iterations, b.reason)
            for field in ("residual", "a_hat", "u0", "uK"):
                assert bits(getattr(a, field)) == bits(getattr(b, field)), f"step {n}: {field}"
            assert bits(ref.b) == bits(fast.b)
        counts = fast.kernel.counts()
        for s_ref, s_fast, (do_step, save, restore) in zip(ref.subsystems, fast.subsystems, counts):
            assert s_ref.calls == s_fast.calls == {"doStep": do_step, "save": save, "restore": restore}
    finally:
        fast.close()
        for s in scenes:
            s.close()


def test_subsystems_hold_x_n_after_a_fast_step(table_i):
    """The kernel saves x_i^n into each Subsystem's own handle, as the reference step does, so
    Subsystem.restore_frozen (energy guard) and thaw work after a fast macro-step too."""
    scene = build_scene(table_i)
    master = FastDRMaster(scene, dataclasses.replace(table_i.master, K=8, fast="true"))
    try:
        for n in range(5):
            log = master.step(n, n * table_i.dt)
        b_fast = list(master.b)
        again = []
        for s, a_i in zip(scene.subsystems, scene.split(log.a_hat)):
            s.restore_frozen()
            again.extend(s.advance(a_i))
        assert bits(again) == bits(b_fast)
    finally:
        master.close()
        scene.close()


def test_trace_matches_reference(table_i):
    """The (u^k, S(u^k)) pairs the FNE watch reads are the reference's."""
    settings = dataclasses.replace(table_i.master, K=8)
    scenes = [build_scene(table_i), build_scene(table_i)]
    ref, fast = DRMaster(scenes[0], settings), FastDRMaster(scenes[1], dataclasses.replace(settings, fast="true"))
    ref.enable_trace(True)
    fast.enable_trace(True)
    try:
        for n in range(20):
            ref.step(n, n * table_i.dt)
            fast.step(n, n * table_i.dt)
            assert len(ref.trace) == len(fast.trace) == 8
            for (u_r, b_r), (u_f, b_f) in zip(ref.trace, fast.trace):
                assert bits(u_r) == bits(u_f) and bits(b_r) == bits(b_f)
    finally:
        fast.close()
        for s in scenes:
            s.close()


def test_retune_between_steps(table_i):
    """A new gamma between macro-steps reaches the kernel: both paths go on bit for bit."""
    settings = dataclasses.replace(table_i.master, K=8)
    scenes = [build_scene(table_i), build_scene(table_i)]
    ref, fast = DRMaster(scenes[0], settings), FastDRMaster(scenes[1], dataclasses.replace(settings, fast="true"))
    try:
        for n in range(40):
            if n == 20:
                for m, scene in zip((ref, fast), scenes):
                    scene.set_gammas({"A": 0.3, "B": 0.3})
                    m.retune([0.5 * x for x in m.b])
            a, b = ref.step(n, n * table_i.dt), fast.step(n, n * table_i.dt)
            assert bits(a.a_hat) == bits(b.a_hat) and bits(ref.b) == bits(fast.b)
    finally:
        fast.close()
        for s in scenes:
            s.close()


def test_two_threads_bit_identical_to_serial(table_i):
    scenario = dataclasses.replace(table_i, T=T_SHORT)
    serial = run(scenario.with_master(K=8, fast="true", threads="1"), certificates=False)
    parallel = run(scenario.with_master(K=8, fast="true", threads="2"), certificates=False)
    runs_identical(serial, parallel)
    scene = build_scene(scenario)
    master = FastDRMaster(scene, dataclasses.replace(scenario.master, K=8, fast="true", threads="2"))
    try:
        for n in range(3):
            master.step(n, n * scenario.dt)
        assert master.threads == 2 and master.kernel.threads == 2
    finally:
        master.close()
        scene.close()


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


def test_multi_channel_scene_bit_identical(built_fmus):
    """A scene with several subsystems of two channels each (configs/chain.yaml), two threads."""
    if "ChainLink" not in built_fmus or not (ROOT / "configs" / "chain.yaml").exists():
        pytest.skip("the ChainLink scene is not available")
    scenario = dataclasses.replace(load_scenario(ROOT / "configs" / "chain.yaml"), T=0.5)
    ref = run(scenario.with_master(K=8, fast="false"), certificates=False)
    for threads in ("1", "2"):
        runs_identical(ref, run(scenario.with_master(K=8, fast="true", threads=threads), certificates=False))


def failing_scenario(newton_max_iter, q1):
    scenario = dataclasses.replace(load_scenario(), T=1.0)
    scenario.subsystems[0].integers["newton_max_iter"] = newton_max_iter
    scenario.subsystems[0].start["q1"] = q1
    return scenario


@pytest.mark.parametrize("newton_max_iter,q1,step", [(1, 3.0, 0), (4, 2.0, 18)])
def test_fmu_error_through_the_kernel(built_fmus, newton_max_iter, q1, step):
    """A failing doStep inside the kernel raises the reference's FmuError, serial or threaded."""
    scenario = failing_scenario(newton_max_iter, q1)
    messages = []
    for fast, threads in (("false", "1"), ("true", "1"), ("true", "2")):
        with pytest.raises(RunFailed) as info:
            run(scenario.with_master(K=3, fast=fast, threads=threads), certificates=False)
        messages.append(str(info.value))
    assert messages[0] == messages[1] == messages[2]
    assert messages[0].startswith(f"subsystem A: fmi2DoStep returned Error at step {step} ")
    assert "Newton step of the Duffing side did not converge" in messages[0]
    scene = build_scene(scenario)
    master = FastDRMaster(scene, dataclasses.replace(scenario.master, K=3, fast="true", threads="1"))
    assert master.kernel.set_threads([1, 0])        # A on the worker thread: its log comes from there
    try:
        with pytest.raises(FmuError) as info:
            for n in range(scenario.n_steps):
                master.step(n, n * scenario.dt)
        assert str(info.value) == messages[0]
        assert (info.value.subsystem, info.value.step) == ("A", step)
    finally:
        master.close()
        scene.close()


def test_fast_true_without_state_support_is_a_config_error(table_i):
    scene = build_scene(table_i)
    try:
        scene.subsystems[1].fmu.can_save_state = False
        with pytest.raises(ConfigError, match="master.fast: true, but subsystem B cannot get and set"):
            FastDRMaster(scene, dataclasses.replace(table_i.master, fast="true"))
        fallback = FastDRMaster(scene, dataclasses.replace(table_i.master, fast="auto"))
        assert not fallback.fast and "subsystem B" in fallback.fast_note
    finally:
        scene.close()


def test_floor_driver_makes_the_same_calls(table_i):
    scene = build_scene(table_i)
    coupling = scene.wave_map()
    kernel = Kernel(scene, coupling.P.tolist(), coupling.J_L.tolist())
    kernel.configure(table_i.dt, 8)
    try:
        kernel.floor(10, 8)
        assert kernel.counts() == [(90, 10, 80)] * 2
    finally:
        kernel.close()
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
    runs_identical(serial, auto)
    note = auto.summary["thread_note"]
    assert note.startswith("2 threads") or note.startswith("serial: 2 threads were not faster"), note


@pytest.mark.parametrize("threads", ["1", "auto"])
def test_run_steps_makes_the_steps_of_step(table_i, threads):
    """run_steps(n0, count) equals count calls of step: a, b^n, calls booked, and it logs what the
    Sampler reads; with a cap below H it stops after one step and undo_step goes back to x^n, b^n.
    threads auto: the first step is timed alone and the rest goes on after it in the kernel's log,
    which grows keeping that step (observe made no room)."""
    from wavecosim.core.readings import Sampler
    settings = dataclasses.replace(table_i.master, K=8, fast="true", threads="1")
    scenes = [build_scene(table_i), build_scene(table_i)]
    one = FastDRMaster(scenes[0], settings)
    block = FastDRMaster(scenes[1], dataclasses.replace(settings, threads=threads))
    sampler = Sampler(scenes[0], table_i.outputs)
    block.observe(sampler.observed)
    try:
        logs = [one.step(n, n * table_i.dt) for n in range(50)]
        reading = sampler.read()
        done, log, error = block.run_steps(0, 50)
        assert (done, error) == (50, None) and bits(one.b) == bits(block.b)
        assert bits([x.a_hat for x in logs]) == bits(log.a_hat)
        assert bits(reading.outputs) == bits(sampler.block(log.observed).outputs[-1])
        assert [s.calls for s in one.subsystems] == [s.calls for s in block.subsystems]
        done, log, error = block.run_steps(50, 10, H_cap=0.0)
        assert (done, error, log.stopped) == (1, None, True)
        b, observed = log.b.copy(), log.observed.copy()          # the next call overwrites the log
        block.undo_step()
        again = block.run_steps(50, 1)[1]
        assert bits(again.b) == bits(b) and bits(again.observed) == bits(observed) and not again.stopped
        assert block.run_steps(51, 1, H_cap=0.0)[1].stopped      # also when it stops after its last step
    finally:
        for m, s in zip((one, block), scenes):
            m.close()
            s.close()
