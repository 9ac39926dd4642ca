"""What the bench's parts share: the Table I scene, timing a master's macro-steps, a fitted slope."""
import time

import numpy as np

from ..examples import path as example
from ..run.runner import BLOCK_STEPS

TABLE_I = example("two_oscillators")


def master_seconds(master, n_steps, dt, blocks=False):
    """Seconds for macro-steps 1 .. n_steps - 1 (step 0 warms up: first calls, caches), one call per
    macro-step or (blocks) in calls of run_steps."""
    master.step(0, 0.0)
    started = time.perf_counter()
    make_steps(master, 1, n_steps, dt, blocks)
    return time.perf_counter() - started


def make_steps(master, n0, n_steps, dt, blocks=False):
    """Macro-steps n0 .. n_steps - 1 of a master: step by step, or in blocks once it can."""
    n, route = n0, master.route()
    while n < n_steps:
        if blocks and route is not None and route.can_run_steps(n):
            done, _, error = route.run_steps(n, min(BLOCK_STEPS, n_steps - n))
            if error is not None:
                raise error
            n += done
        else:
            master.step(n, n * dt)
            n += 1


def slope(x, y):
    """Least-squares slope of y against x: the marginal cost of one more inner iteration."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    return float(np.polyfit(x, y, 1)[0])
