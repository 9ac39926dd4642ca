"""The ChainLink FMU (models/chain_link/): its two channels have opposite causality and one doStep is
the implicit midpoint step. Validation, passivity and rollback run with the other models in
tests/test_models.py."""

import numpy as np
import pytest
from fmpy import extract

from test_models import Instance, channels

PASSIVITY_RTOL = 1e-12
STATES = {"q": 0.5, "v": 1.0, "d": 0.3}
DAMPERS = ("c", "c0")


@pytest.fixture(scope="module")
def fmus(built_fmus, tmp_path_factory):
    path = built_fmus["ChainLink"]
    return {"ChainLink": (path, extract(str(path), unzipdir=str(tmp_path_factory.mktemp("ChainLink"))))}


def random_link(fmus, rng, mode, damped):
    reals = {k: s * rng.standard_normal() for k, s in STATES.items()}
    reals.update(m=10.0 ** rng.uniform(-1, 1), k=10.0 ** rng.uniform(0, 3), k0=rng.uniform(0.0, 50.0),
                 gamma=10.0 ** rng.uniform(-1.5, 1.5))
    reals.update({c: rng.uniform(0.0, 2.0) if damped else 0.0 for c in DAMPERS})
    return Instance(fmus, "ChainLink", reals=reals, ints={"port_mode": mode})


def test_channels_have_opposite_causality():
    assert [c[5] for c in channels("chain_link")] == ["EFFORT_INPUT", "FLOW_INPUT"]


def test_step_matches_the_midpoint_rule(fmus):
    """Physical mode, one step: the link's closed form equals the implicit midpoint rule of
    m v' = -k0 q - c0 v - F + k d + c (u - v), d' = u - v, solved here as a 3x3 linear system."""
    p = dict(m=2.0, k=50.0, c=0.3, k0=7.0, c0=0.2)
    x0 = np.array([0.1, -0.4, 0.05])  # q, v, d
    F, u, h = 1.5, 0.7, 0.02
    link = Instance(fmus, "ChainLink", reals={**p, "q": x0[0], "v": x0[1], "d": x0[2]}, ints={"port_mode": 1})
    try:
        link.set(F_left=F, u_right=u)
        link.step(h)
        got = link.get("q", "v", "d")
    finally:
        link.free()
    A = np.array([[0.0, 1.0, 0.0],
                  [-p["k0"] / p["m"], -(p["c0"] + p["c"]) / p["m"], p["k"] / p["m"]],
                  [0.0, -1.0, 0.0]])
    g = np.array([0.0, (-F + p["c"] * u) / p["m"], u])
    want = np.linalg.solve(np.eye(3) - 0.5 * h * A, (np.eye(3) + 0.5 * h * A) @ x0 + h * g)
    assert np.allclose(got, want, rtol=1e-13, atol=1e-15)
