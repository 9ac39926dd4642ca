"""The newton master on the kernel route gives its Python reference's numbers to the last bit.

Claims: with `master.fast` (auto, as DR) the interface Newton and the commit of each macro-step run in
C (kernel/c/newton.c) and, on every shipped scene (wave adapters included), give trajectories,
per-step logs and FMU call counts equal bit for bit to `fast: false`, also across a change of gamma
between macro-steps (auto-retune's); an FMU error and a Newton that does not converge come back as the reference's
one-line errors; the reference's LU solve (linalg.solve) has numpy's bits on 1 x 1 and 2 x 2 systems,
so moving the reference off numpy's LAPACK changed no number of the two-subsystem scenes.
"""
import copy
import dataclasses

import numpy as np
import pytest
import yaml

from conftest import python_and_kernel_masters
from paths import ROOT
from wavecosim.scenario.config import DEFAULT_CONFIG, load_scenario, parse_scenario
from wavecosim.core.gamma import rescatter
from wavecosim.kernel.linalg import solve
from wavecosim.run.runner import RunFailed, run

SCENES = {"two_oscillators": 1.0, "two_oscillators_stiff": 1.0, "chain": 0.5, "star": 0.5, "planar": 0.5,
          "rlc_motor": 0.5, "pendulum_cart": 0.5, "heavy_chain": 0.2,
          "foreign_pair": 0.1, "fmi3_damper": 0.1, "dcmotor": 0.05, "dcmotor_shaft": 0.05}   # name: T
THIRD_PARTY = ROOT.parent / "shared" / "third_party"
RETUNE = dict(k12=1.2e5, dt=0.1, m2=400.0)   # test_gamma_tuning's scene where gamma falls between steps


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


def runs_identical(a, b):
    assert a.status == b.status
    assert bits(a.outputs) == bits(b.outputs), "trajectories differ"
    for key in a.steps.dtype.names:
        assert a.steps[key].tobytes() == b.steps[key].tobytes(), f"per-step {key} differs"
    assert a.summary["fmu_calls"] == b.summary["fmu_calls"]


def both(sc):
    """The run on the Python reference and on the kernel route."""
    ref = run(sc.with_master(fast="false"), certificates=False)
    fast = run(sc.with_master(fast="true"), certificates=False)
    assert ref.summary["fast_path"] is False and fast.summary["fast_path"] is True
    return ref, fast


def oscillators(gamma, T, k12, dt, m2):
    raw = copy.deepcopy(yaml.safe_load(DEFAULT_CONFIG.read_text()))
    raw["subsystems"]["A"]["parameters"]["k12"] = k12
    raw["subsystems"]["B"]["parameters"]["m2"] = m2
    raw.update(dt=dt, T=T, gamma=gamma)
    raw["master"].update(algorithm="newton")
    return parse_scenario(raw, f"k12={k12:g},gamma={gamma}", DEFAULT_CONFIG.parent)


@pytest.mark.parametrize("name", SCENES)
def test_kernel_route_is_bit_identical_to_the_reference(name, built_fmus):
    path = ROOT / "configs" / f"{name}.yaml"
    if "third_party" in path.read_text() and not THIRD_PARTY.exists():
        pytest.skip("needs ../shared/third_party (third-party FMUs)")
    sc = load_scenario(path)
    sc = dataclasses.replace(sc, T=min(sc.T, SCENES[name])).with_master(algorithm="newton")
    ref, fast = both(sc)
    runs_identical(ref, fast)
    assert fast.summary["fast_note"].startswith("C kernel")


def test_subsystems_hold_x_n_and_b_after_kernel_steps_and_a_retune(built_fmus):
    """Direct steps of both masters: after a change of gamma (P recompiled, b^n re-scattered, as
    auto-retune does it) and an undo and recommit they hold the same b and made the same FMU calls."""
    sc = load_scenario(ROOT / "configs" / "two_oscillators_stiff.yaml").with_master(algorithm="newton")
    with python_and_kernel_masters(sc) as (masters, scenes):
        logs = []
        for m, scene in zip(masters, scenes):
            logs.append([m.step(n, n * sc.dt) for n in range(3)])
            b_new = rescatter(scene, {"A": 7.0, "B": 0.05})
            scene.set_gammas({"A": 7.0, "B": 0.05})
            m.retune(b_new)
            logs[-1] += [m.step(n, n * sc.dt) for n in range(3, 6)]
        assert [bits(log.a_hat) for log in logs[0]] == [bits(log.a_hat) for log in logs[1]]
        for m in masters:
            m.undo_step()                                     # back to x^5 through the saved state
            m.recommit(logs[0][-1].a_hat)
        assert bits(masters[0].b) == bits(masters[1].b)
        assert [s.calls for s in scenes[0].subsystems] == [s.calls for s in scenes[1].subsystems]


def failures(sc):
    messages = []
    for fast in ("false", "true"):
        with pytest.raises(RunFailed) as info:
            run(sc.with_master(fast=fast), certificates=False)
        messages.append((str(info.value), info.value.exit_code))
    assert messages[0] == messages[1]
    return messages[0]


def test_fmu_error_through_the_newton_kernel(built_fmus):
    sc = load_scenario(ROOT / "configs" / "two_oscillators.yaml").with_master(algorithm="newton")
    sc.subsystems[0].integers["newton_max_iter"] = 1
    sc.subsystems[0].start["q1"] = 3.0
    message, code = failures(sc)
    assert code == 3 and message.startswith("subsystem A: fmi2DoStep returned Error at step ")


def test_newton_that_does_not_converge_through_the_kernel(built_fmus):
    """At gamma = 0.4 the interface Newton does not converge on the RETUNE scene (test_gamma_tuning)."""
    message, code = failures(oscillators(0.4, 10.0, **RETUNE))
    assert code == 4 and message.startswith("interface Newton at step ") and "did not converge" in message


@pytest.mark.parametrize("n", [1, 2])
def test_solve_has_numpys_bits_on_small_systems(n):
    rng = np.random.default_rng(n)
    for k in range(2000):
        A = rng.normal(size=(n, n)) if k % 2 else np.eye(n) - rng.normal(size=(n, n)) * 10.0 ** rng.integers(-8, 1)
        b = rng.normal(size=n)
        assert solve(A, b).tobytes() == np.linalg.solve(A, b).tobytes()


def test_solve_of_a_singular_matrix_is_none():
    assert solve([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]) is None
    x = solve([[0.0, 2.0], [3.0, 1.0]], [4.0, 5.0])                  # needs the row swap
    assert x.tolist() == [1.0, 2.0]


def test_the_sparse_lu_gives_the_dense_solve_numbers():
    """linalg.solve_sparse (the interface Newton's solve, kernel/c/newton.c's lu_sparse) gives solve()'s
    numbers on random sparse systems, row swaps, zero right-hand sides and singular ones included."""
    from wavecosim.kernel.linalg import solve_sparse
    rng = np.random.default_rng(7)
    for _ in range(500):
        n = int(rng.integers(1, 12))
        mask = rng.random((n, n)) < rng.uniform(0.1, 0.6)
        A = np.where(mask, rng.standard_normal((n, n)) * 10.0 ** rng.integers(-3, 4, (n, n)), 0.0)
        if rng.random() < 0.5:
            A += np.diag(rng.standard_normal(n))
        b = np.where(rng.random(n) < 0.2, 0.0, rng.standard_normal(n))
        dense, sparse = solve(A, b), solve_sparse([{j: v for j, v in enumerate(row) if v != 0.0} for row in A], b)
        assert (dense is None) == (sparse is None)
        if dense is not None:
            assert np.array_equal(dense, sparse)
