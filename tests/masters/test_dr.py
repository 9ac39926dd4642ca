"""Algorithm 1 (paper eqs. 17-21) on a linear case with a known answer and on the real FMUs."""
import numpy as np
import pytest

from wavecosim.scenario.config import load_scenario
from wavecosim.masters.dr import DRMaster, algorithm1
from wavecosim.masters.monolithic import solve_interface
from wavecosim.core.scene import build_scene

SWAP = [[0.0, 1.0], [1.0, 0.0]]
J_SWAP = (np.linalg.inv(2 * np.eye(2) - np.array(SWAP))).tolist()


def affine_map(rho, c):
    """A frozen port map b = rho * a + c per channel: FNE for 0 <= rho <= 1."""
    return lambda u: [r * x + ci for r, x, ci in zip(rho, u, c)]


def test_k0_is_the_explicit_wave_interface():
    log = algorithm1(affine_map([0.5, 0.2], [1.0, -1.0]), SWAP, J_SWAP, [0.3, -0.7], K=0)
    assert log.a_hat == [-0.7, 0.3] and log.iterations == 0 and log.reason == "explicit"


def test_one_iteration_by_hand():
    S = affine_map([0.5, 0.2], [1.0, -1.0])
    b_n = [0.3, -0.7]
    u0 = [-0.7, 0.3]
    b_hat = S(u0)
    log = algorithm1(S, SWAP, J_SWAP, b_n, K=1)
    assert log.a_hat == [b_hat[1], b_hat[0]]
    w = np.array(J_SWAP) @ (2 * np.array(b_hat) - np.array(u0))
    assert np.allclose(log.uK, np.array(u0) + w - np.array(b_hat), rtol=0, atol=1e-15)


def test_linear_case_converges_to_the_known_fixed_point():
    rho, c = [0.6, 0.3], [1.0, -2.0]
    # b_A = rho_A b_B + c_A, b_B = rho_B b_A + c_B
    M = np.array([[1.0, -rho[0]], [-rho[1], 1.0]])
    b_star = np.linalg.solve(M, c)
    log = algorithm1(affine_map(rho, c), SWAP, J_SWAP, [0.0, 0.0], K=200)
    assert np.allclose(log.a_hat, np.array(SWAP) @ b_star, atol=1e-13)
    assert np.allclose(log.uK, np.array(SWAP) @ b_star, atol=1e-13)  # u* = P b* (eq. 18)


def test_tolerance_exit_reports_reason_and_iterations():
    log = algorithm1(affine_map([0.6, 0.3], [1.0, -2.0]), SWAP, J_SWAP, [0.0, 0.0], K=1000, eps=1e-9)
    assert log.reason == "tolerance" and 5 < log.iterations < 1000 and log.residual <= 1e-9


@pytest.fixture(scope="module")
def frozen_benchmark():
    """Table I FMUs advanced 40 steps by DR, then frozen: S^n at a nontrivial state."""
    scenario = load_scenario()
    scene = build_scene(scenario)
    master = DRMaster(scene, scenario.master)
    for n in range(40):
        master.step(n, n * scenario.dt)
    scene.freeze(40, 40 * scenario.dt)
    yield scene, master
    scene.close()


def test_fejer_monotonicity_of_inner_iterates(frozen_benchmark):
    scene, master = frozen_benchmark
    b_star = solve_interface(scene, master.P, master.b)[0]
    u_dag = np.array(master.P) @ b_star
    iterates = []

    def recording_S(u):
        iterates.append(np.array(u))
        return scene.S(u)
    log = algorithm1(recording_S, master.P, master.J_L, master.b, K=60)
    iterates.append(np.array(log.uK))
    dist = [float(np.sum((u - u_dag) ** 2)) for u in iterates]
    for k in range(len(iterates) - 1):
        step = float(np.sum((iterates[k + 1] - iterates[k]) ** 2))
        assert dist[k + 1] <= dist[k] - step + 1e-12 * (1 + dist[0])   # eq. (28)
    assert dist[-1] < 1e-6 * dist[0]


def test_monolithic_newton_matches_converged_dr(frozen_benchmark):
    scene, master = frozen_benchmark
    b_star, iters, res, _ = solve_interface(scene, master.P, master.b)
    log = algorithm1(scene.S, master.P, master.J_L, master.b, K=400)
    assert res < 1e-12 and iters < 10
    assert np.allclose(np.array(master.P) @ b_star, log.a_hat, rtol=0, atol=1e-11)
    # and the fixed point really is one: b* = S(P b*)
    assert np.allclose(scene.S(list(np.array(master.P) @ b_star)), b_star, rtol=0, atol=1e-12)


def test_frozen_map_never_changes_the_committed_state(frozen_benchmark):
    scene, master = frozen_benchmark
    A = scene.subsystems[0]
    names = ["q1", "v1", "d"]
    A.thaw()
    before = list(A.read(names))
    for a in (-3.0, 0.5, 40.0):
        A.query([a])
    A.thaw()
    assert list(A.read(names)) == before
