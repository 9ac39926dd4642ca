"""The ChainLink FMU (models/chain_link/): validates, takes one discrete-passive step per doStep in
both port modes (equality when undamped), honours the wave closure, and rolls back bit-identically.

The same checks as tests/test_models.py, on the link's two channels of opposite causality.
"""
import zlib

import numpy as np
import pytest
from fmpy import extract
from fmpy.validation import validate_fmu

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


def test_validates(fmus):
    assert validate_fmu(str(fmus["ChainLink"][0])) == []


def test_channels_have_opposite_causality():
    assert [c[5] for c in channels("chain_link")] == ["EFFORT_INPUT", "FLOW_INPUT"]


@pytest.mark.parametrize("mode", [0, 1], ids=["wave", "physical"])
def test_discrete_passivity(fmus, mode):
    """H(x1) - H(x0) = h e.f - dissipation over 100 random (state, input, gamma, h, parameters)."""
    rng = np.random.default_rng(zlib.crc32(f"ChainLink{mode}".encode()))
    chans = channels("chain_link")
    for trial in range(10):
        damped = trial % 2 == 1
        link = random_link(fmus, rng, mode, damped)
        try:
            for _ in range(10):
                h = 10.0 ** rng.uniform(-3, -1)
                gamma = 10.0 ** rng.uniform(-1.5, 1.5)
                link.set(gamma=gamma)
                H0 = link.get("H")[0]
                if mode == 0:
                    a = rng.standard_normal(2) * np.sqrt(h * (abs(H0) + 1.0))
                    link.set(**{c[0]: x for c, x in zip(chans, a)})
                else:
                    link.set(**{c[4]: rng.standard_normal() for c in chans})
                link.step(h)
                H1 = link.get("H")[0]
                e = link.get(*[c[2] for c in chans])
                f = link.get(*[c[3] for c in chans])
                supply = h * float(e @ f)
                resid = (H1 - H0 - supply) / (abs(H0) + abs(H1) + abs(supply) + 1e-300)
                assert resid <= PASSIVITY_RTOL
                if not damped:
                    assert abs(resid) <= PASSIVITY_RTOL
                if mode == 0:
                    b = link.get(*[c[1] for c in chans])
                    target = np.sqrt(2.0 * gamma / h) * a
                    assert np.allclose(e + gamma * f, target, rtol=1e-11, atol=1e-11 * np.abs(target).max())
                    assert abs(0.5 * (a @ a - b @ b) - supply) <= 1e-11 * (a @ a + b @ b + 1e-300)
                else:  # the held inputs are the port values: F_left is e_left, u_right is f_right
                    assert link.get("e_left")[0] == link.get("F_left")[0]
                    assert link.get("f_right")[0] == link.get("u_right")[0]
        finally:
            link.free()


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


def test_rollback_is_bit_identical(fmus):
    rng = np.random.default_rng(7)
    chans = channels("chain_link")
    link = random_link(fmus, rng, mode=0, damped=True)
    try:
        h = 0.01
        for _ in range(3):
            link.set(**{c[0]: 0.1 * rng.standard_normal() for c in chans})
            link.step(h)
        inputs = {c[0]: 0.1 * rng.standard_normal() for c in chans}
        state = link.fmu.getFMUState()
        restored = link.fmu.deserializeFMUState(link.fmu.serializeFMUState(state))
        runs = []
        for saved in (None, state, restored):
            if saved is not None:
                link.fmu.setFMUState(saved)
                link.t -= 2 * h
            link.set(**inputs)
            link.step(h)
            link.step(h)
            runs.append(link.get(*link.reals).tobytes())
        link.fmu.freeFMUState(state)
        link.fmu.freeFMUState(restored)
        assert runs[0] == runs[1] == runs[2]
    finally:
        link.free()
