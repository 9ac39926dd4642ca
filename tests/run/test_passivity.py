"""observers/passivity.py: Condition 2 over a block of macro-steps (its C pass over the kernel's log,
kernel/c/blocks.c passivity_steps, made in parts as the kernel and the runner make it) gives
after_step's numbers step after step, to the last bit, where the order of every sum shows: wave and
physical ports, one and two channels per port."""
import numpy as np
import pytest

from paths import ROOT
from wavecosim.scenario.config import load_scenario
from wavecosim.kernel import blocks
from wavecosim.kernel.drkernel import LEDGER_LOG, BlockLog
from wavecosim.masters.base import StepLog
from wavecosim.run.observers.passivity import Passivity
from wavecosim.core.readings import Reading, Sampler
from wavecosim.core.scene import build_scene

STEPS = 300


def adversarial(rng, shape):
    """Values of both signs over 16 decades, so that sums of a few of them depend on their order."""
    return rng.standard_normal(shape) * 10.0 ** rng.integers(-8, 9, shape)


def block_and_steps(scene, outputs, rng):
    """A kernel log of STEPS steps with adversarial values, as a BlockLog with its BlockReading, and
    the same steps as (StepLog, Reading) pairs."""
    sampler, n = Sampler(scene, outputs), scene.n_channels
    observed = sum(len(names) for names in sampler.observed)
    columns = adversarial(rng, (3 + 2 * n + observed + len(LEDGER_LOG), STEPS))
    log = BlockLog(columns, n)
    readings = sampler.block(log.observed)
    steps = [(StepLog(a_hat=log.a_hat[s].tolist()),
              Reading(readings.H[s].tolist(), readings.E[s].tolist(), readings.F[s].tolist(),
                      readings.B[s].tolist(), [])) for s in range(STEPS)]
    return log, readings, steps


@pytest.mark.parametrize("config,wave", [("two_oscillators.yaml", True), ("planar.yaml", True),
                                         ("two_oscillators.yaml", False), ("planar.yaml", False)])
def test_a_block_is_its_steps_to_the_bit(built_fmus, config, wave):
    scenario = load_scenario(ROOT / "configs" / config)
    scene = build_scene(scenario, wave=wave, needs_rollback=False)
    try:
        log, readings, steps = block_and_steps(scene, scenario.outputs, np.random.default_rng(7))
        first = Reading([1e16, 1.0], [], [], [], [])          # H_total 1e16 + 1: its order shows
        by_step, by_block = Passivity(scene), Passivity(scene)
        assert by_block.blocks
        width = len(by_step.columns)
        step_rows, block_rows = np.empty((STEPS, width)), np.empty((STEPS, width), order="F")
        by_step.start(first)
        by_block.start(first)
        for s, (step_log, reading) in enumerate(steps):
            by_step.after_step(s, s * 0.01, step_log, reading, step_rows[s])
        by_block.prepare_block(log.first(0), readings)
        block = by_block.block_pass()
        block.args.out, block.args.ldo = blocks.columns(block_rows)
        for first, end in ((0, 100), (100, 228), (228, STEPS)):     # parts across the passes' 128-step chunks
            block.steps(0, log, first, end - first)
        assert step_rows.tobytes() == block_rows.tobytes()
        assert repr(by_step.summary()) == repr(by_block.summary())
        figures = (lambda o: repr((o.prev[:], o.fig[:], o.ledger[:])))      # H before, maxima, drift, H_max, ...
        assert figures(by_step) == figures(by_block)
    finally:
        scene.close()
