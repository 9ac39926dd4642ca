"""The classical masters on the kernel route give their Python reference's numbers to the last bit.

Claims: explicit, gauss-seidel, jacobi-iter and gauss-seidel-iter with `master.fast` (auto, as DR)
run in C (kernel/c/classical.c), through the runner in blocks of macro-steps per kernel call,
and, on every shipped scene they can run (the fixed-point masters at K = 0, 3 and 10 with a
tolerance), give trajectories, per-step logs and FMU call counts equal bit for bit to `fast: false`;
blocks and one kernel call per step leave the same logs, outputs, inputs and calls;
the energy ledger guard (undo, redo) works on it alike, step by step; a run that blows up fails
alike in blocks; an FMU error comes back as the reference's FmuError; a declared physical port keeps the Python reference (`fast: true` then is a config error).
"""
import dataclasses
import math

import numpy as np
import pytest

from conftest import python_and_kernel_masters
from paths import ROOT
from wavecosim.scenario.config import load_scenario
from wavecosim.errors import ConfigError
from wavecosim.masters import MASTERS
from wavecosim.run.runner import RunFailed, run
from wavecosim.core.scene import build_scene

SCENES = ("two_oscillators", "two_oscillators_stiff", "chain", "star", "planar", "rlc_motor", "pendulum_cart")
MASTER_NAMES = ("jacobi-iter", "gauss-seidel-iter")
T_TEST = 1.0


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


def scenario(name, **master):
    sc = dataclasses.replace(load_scenario(ROOT / "configs" / f"{name}.yaml"), T=T_TEST)
    return sc.with_master(**master)


def runs_identical(a, b):
    assert a.status == b.status
    assert bits(a.outputs) == bits(b.outputs), "trajectories differ"
    for key in a.steps.dtype.names:
        assert a.steps[key].tobytes() == b.steps[key].tobytes(), f"per-step {key} differs"
    assert a.summary["fmu_calls"] == b.summary["fmu_calls"]


@pytest.mark.parametrize("K, eps", [(0, None), (3, None), (10, 1e-9)])
@pytest.mark.parametrize("master", MASTER_NAMES)
@pytest.mark.parametrize("name", SCENES)
def test_kernel_route_is_bit_identical_to_the_reference(name, master, K, eps, built_fmus):
    sc = scenario(name, algorithm=master, K=K, eps=eps, energy_guard="off")
    ref = run(sc.with_master(fast="false"), certificates=False)
    fast = run(sc.with_master(fast="auto"), certificates=False)
    assert ref.summary["fast_path"] is False and fast.summary["fast_path"] is True
    assert ref.summary["block_steps"] == 0 and fast.summary["block_steps"] == sc.n_steps
    runs_identical(ref, fast)


@pytest.mark.parametrize("master", ["explicit", "gauss-seidel"])
@pytest.mark.parametrize("name", SCENES)
def test_explicit_masters_on_the_kernel_route(name, master, built_fmus):
    sc = scenario(name, algorithm=master)
    ref = run(sc.with_master(fast="false"), certificates=False)
    fast = run(sc.with_master(fast="auto"), certificates=False)
    assert ref.summary["fast_path"] is False and fast.summary["fast_path"] is True
    runs_identical(ref, fast)
    assert fast.summary["fmu_calls"]["save"] == 0                      # nothing saved, as in Python
    assert fast.summary["block_steps"] == sc.n_steps


@pytest.mark.parametrize("master, K", [("explicit", 0), ("gauss-seidel", 0), ("jacobi-iter", 3),
                                       ("gauss-seidel-iter", 10)])
def test_blocks_equal_one_kernel_call_per_step(master, K, built_fmus):
    """Blocks of 7 steps (the last one short) against step() on the kernel: the same per-step logs,
    y^{n+1}, committed inputs and FMU calls, and undo_step after a block goes back as after step()."""
    sc = scenario("two_oscillators_stiff", algorithm=master, K=K, eps=1e-12)
    settings, steps = dataclasses.replace(sc.master, fast="true"), 40
    scenes = [build_scene(sc, wave=False) for _ in range(2)]
    by_step, by_block = [MASTERS[master](s, settings) for s in scenes]
    try:
        logs = [by_step.step(n, n * sc.dt) for n in range(steps)]
        blocks, n = [], 0
        while n < steps:
            done, log, error = by_block.run_steps(n, min(7, steps - n))
            assert error is None and done == min(7, steps - n)
            blocks += [by_block.step_log(log, j) for j in range(done)]
            n += done
        assert [(g.iterations, g.reason) for g in logs] == [(g.iterations, g.reason) for g in blocks]
        assert bits([g.residual for g in logs]) == bits([g.residual for g in blocks])
        assert bits(by_step.y) == bits(by_block.y)
        assert [s.calls for s in scenes[0].subsystems] == [s.calls for s in scenes[1].subsystems]
        if K:
            assert bits(by_step.u) == bits(by_block.u)
            for m in (by_step, by_block):
                m.undo_step()
                m.recommit(m.u)
            assert bits(by_step.y) == bits(by_block.y) and bits(by_step.y_step_start) == bits(by_block.y_step_start)
    finally:
        for m, s in zip((by_step, by_block), scenes):
            m.close()
            s.close()


@pytest.mark.parametrize("master", MASTER_NAMES)
def test_ledger_guard_redoes_the_same_steps_on_the_kernel_route(master, built_fmus):
    sc = scenario("two_oscillators_stiff", algorithm=master, K=1, energy_guard="ledger")
    ref = run(sc.with_master(fast="false"), certificates=False)
    fast = run(sc.with_master(fast="true"), certificates=False)
    assert fast.summary["energy_guard_steps"] > 0 or master == "gauss-seidel-iter"   # (none needed there)
    assert fast.summary["energy_guard_steps"] == ref.summary["energy_guard_steps"]
    assert fast.summary["block_steps"] == 0                            # the ledger keeps it step by step
    runs_identical(ref, fast)


def test_subsystems_hold_x_n_and_y_after_a_kernel_step(built_fmus):
    sc = scenario("two_oscillators", algorithm="gauss-seidel-iter", K=3)
    with python_and_kernel_masters(sc, wave=False) as (masters, scenes):
        for n in range(5):
            for m in masters:
                m.step(n, n * sc.dt)
        for m in masters:
            m.undo_step()                                     # back to x^4 through the saved state
            m.recommit(m.u)
        assert bits(masters[0].y) == bits(masters[1].y) and bits(masters[0].u) == bits(masters[1].u)
        assert [s.calls for s in scenes[0].subsystems] == [s.calls for s in scenes[1].subsystems]


def test_fmu_error_through_the_classical_kernel(built_fmus):
    sc = scenario("two_oscillators", algorithm="jacobi-iter", K=3)
    sc.subsystems[0].integers["newton_max_iter"] = 1
    sc.subsystems[0].start["q1"] = 3.0
    messages = []
    for fast in ("false", "true"):
        with pytest.raises(RunFailed) as info:
            run(sc.with_master(fast=fast), certificates=False)
        messages.append(str(info.value))
    assert messages[0] == messages[1] and messages[0].startswith("subsystem A: fmi2DoStep returned Error at step ")


def test_declared_physical_ports_keep_the_reference(built_fmus):
    sc = scenario("foreign_pair", algorithm="jacobi-iter", K=2)
    result = run(sc, certificates=False)
    assert result.summary["fast_path"] is False and "physical port" in result.summary["fast_note"]
    with pytest.raises(ConfigError) as exc:
        run(sc.with_master(fast="true"), certificates=False)
    assert "\n" not in str(exc.value) and "master.fast: true, but subsystem A has a declared physical port" in str(exc.value)


@pytest.mark.parametrize("bound, why", [(1e12, "has grown past 1e+12"), (math.inf, "fmi2DoStep returned Error")])
def test_a_diverging_run_fails_alike_in_blocks(built_fmus, bound, why):
    """Explicit coupling on the stiff scene blows up until its outputs pass the growth bound (or,
    without one, until an FMU fails): in blocks (with an output interval) the same failure at the
    same step, and the same rows before it, as the Python loop."""
    sc = dataclasses.replace(scenario("two_oscillators_stiff", algorithm="explicit"), T=20.0, growth_bound=bound)
    failed = []
    for fast in ("false", "true"):
        with pytest.raises(RunFailed) as info:
            run(sc.with_master(fast=fast), certificates=False, output_interval=7)
        failed.append(info.value)
    assert str(failed[0]) == str(failed[1]) and why in str(failed[0])
    assert failed[1].result.summary["block_steps"] > 0
    runs_identical(failed[0].result, failed[1].result)
