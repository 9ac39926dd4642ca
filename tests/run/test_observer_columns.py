"""A steps.csv column defined by one function over a block of steps (Observer.block): the runner
hands it a block of the kernel's steps or a single step as a block of one, and the column is the
same to the last bit either way."""
import numpy as np

from paths import CONFIGS
from wavecosim.core.readings import row_dots
from wavecosim.run import live, runner
from wavecosim.run.observers import Observer
from wavecosim.scenario.config import load_scenario


class Traffic(Observer):
    """½(|a|² + |b|²) of every step and the H of the first subsystem, as one numpy function."""
    blocks = True
    columns = ("traffic", "H_first")

    def block(self, n0, logs, readings):
        a, b = logs.a_hat, readings.B
        return np.column_stack([0.5 * (row_dots(a, a) + row_dots(b, b)), readings.H[:, 0]])


def columns_of(monkeypatch, size):
    """The Traffic columns of Table I's first 300 steps (DR, K = 8) made in blocks of `size` steps."""
    scenario = load_scenario(CONFIGS / "two_oscillators.yaml").with_master(K=8).with_changes(T=3.0)
    with monkeypatch.context() as m:
        m.setattr(live, "BLOCK_STEPS", size)
        run = live.LiveRun(scenario, certificates=False)
        run.add_observer(Traffic())
        status, error = runner._loop(run, None, None)
        result = run.finish(status, str(error or ""))
    assert status == "finished" and (result.summary["block_steps"] > 0) == (size > 1)
    return result.steps["traffic"], result.steps["H_first"]


def test_a_column_of_one_function_is_the_same_step_by_step_and_in_blocks(monkeypatch):
    steps, blocks = columns_of(monkeypatch, 1), columns_of(monkeypatch, runner.BLOCK_STEPS)
    assert len(steps[0]) == 300 and np.all(steps[0] > 0.0)
    for one, many in zip(steps, blocks):
        assert one.tobytes() == many.tobytes()
