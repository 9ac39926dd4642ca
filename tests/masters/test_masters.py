"""The classical masters on the real benchmark FMUs: what they cost, what they converge to, and the
energy-safety contrast on the stiff scene (explicit masters pump energy in, DR never does)."""
import dataclasses

import numpy as np
import pytest

from paths import ROOT
from wavecosim.scenario.config import load_scenario
from wavecosim.masters import MASTERS
from wavecosim.run.runner import run
from wavecosim.sweeps.budget import reference_run

TABLE_I = ROOT / "configs" / "two_oscillators.yaml"
STIFF = ROOT / "configs" / "two_oscillators_stiff.yaml"


def scenario(path, T, **master):
    return dataclasses.replace(load_scenario(path).with_master(**master), T=T)


def run_quiet(sc, **kw):
    return run(sc, certificates=kw.pop("certificates", False), warn=lambda line: None, **kw)


@pytest.fixture(scope="module")
def reference():
    return reference_run(scenario(TABLE_I, 2.0))


def test_classical_masters_are_registered_in_physical_mode():
    for name in ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter"):
        assert MASTERS[name].wave is False, name
    assert MASTERS["explicit"].needs_rollback is False
    assert MASTERS["gauss-seidel"].needs_rollback is False


@pytest.mark.parametrize("name", ["explicit", "gauss-seidel"])
def test_explicit_masters_step_once_and_never_roll_back(name):
    s = run_quiet(scenario(TABLE_I, 1.0, algorithm=name)).summary
    # per step and subsystem: its inputs set, one doStep, its outputs read, and the run's reading after the step
    assert s["fmu_calls"] == {"doStep": 2 * 100, "save": 0, "restore": 0, "get": 2 * 2 * 100, "set": 2 * 100}
    assert s["iterations_max"] == 0


@pytest.mark.parametrize("name", ["jacobi-iter", "gauss-seidel-iter"])
def test_fixed_point_masters_count_queries_saves_and_restores(name):
    K, N = 3, 100
    s = run_quiet(scenario(TABLE_I, 1.0, algorithm=name, K=K)).summary
    # per step and subsystem: one save, K queries and one commit, each after a restore but the first,
    # each a set, a doStep and a get; and the run's reading after the step
    assert s["fmu_calls"] == {"doStep": 2 * N * (K + 1), "save": 2 * N, "restore": 2 * N * K,
                              "get": 2 * N * (K + 1) + 2 * N, "set": 2 * N * (K + 1)}
    assert s["iterations_max"] == K and s["iterations_mean"] == K


@pytest.mark.parametrize("iterated, explicit", [("jacobi-iter", "explicit"), ("gauss-seidel-iter", "gauss-seidel")])
def test_budget_zero_is_the_explicit_master(iterated, explicit):
    # the explicit masters cannot roll back, so no energy guard holds them: compare without one
    a = run_quiet(scenario(TABLE_I, 1.0, algorithm=iterated, K=0, energy_guard="off"))
    b = run_quiet(scenario(TABLE_I, 1.0, algorithm=explicit))
    assert np.array_equal(a.outputs, b.outputs)


def test_gauss_seidel_order_differs_from_jacobi():
    a = run_quiet(scenario(TABLE_I, 1.0, algorithm="explicit"))
    b = run_quiet(scenario(TABLE_I, 1.0, algorithm="gauss-seidel"))
    assert not np.allclose(a.outputs, b.outputs)


@pytest.mark.parametrize("name", ["jacobi-iter", "gauss-seidel-iter"])
def test_fixed_point_error_falls_with_budget_to_the_monolithic_step(name, reference):
    errors = [run_quiet(scenario(TABLE_I, 2.0, algorithm=name, K=K), reference=reference).summary["max_error"]
              for K in (1, 2, 3, 10)]
    assert errors[0] > errors[1] > errors[2] > errors[3], errors
    assert errors[3] < 1e-12, errors                      # the converged fixed point is the monolithic step


def test_tolerance_stops_the_iteration_early(reference):
    s = run_quiet(scenario(TABLE_I, 2.0, algorithm="jacobi-iter", K=50, eps=1e-11), reference=reference).summary
    assert s["iterations_max"] < 50
    assert s["max_error"] < 1e-9


def test_deadline_stops_after_one_iteration():
    sc = scenario(TABLE_I, 0.5, algorithm="gauss-seidel-iter", K=50, deadline_us=1e-3)
    result = run_quiet(sc)
    assert set(result.steps["iterations"]) == {1}


# ---------------------------------------------------------------- energy safety on the stiff scene

@pytest.mark.parametrize("name", ["explicit", "gauss-seidel"])
def test_explicit_masters_inject_energy_into_the_stiff_scene(name):
    result = run_quiet(scenario(STIFF, 1.0, algorithm=name))
    s, H = result.summary, np.array(result.energy)
    assert H.max() > 1e6 * H[0]                           # a lossless, damped scene gains energy: injected
    assert s["max_passivity_pos"] < 1e-9 * H.max()        # each subsystem is passive on its own port ...
    assert s["energy_drift"] >= 0.99 * (H[-1] - H[0])     # ... so the gain came in through the interface


@pytest.mark.parametrize("K", [0, 1, 3, 8, 50])
def test_dr_never_injects_energy_into_the_stiff_scene(K):
    result = run_quiet(scenario(STIFF, 1.0, algorithm="dr", K=K), certificates=True)
    s, H = result.summary, np.array(result.energy)
    assert s["min_fne_margin"] >= 0.0                     # Condition 1 holds at this gamma (the premise)
    assert H.max() <= H[0] * (1 + 1e-12)                  # stored energy never exceeds H(0)
    assert s["max_passivity_pos"] <= 1e-12 * H[0]         # Condition 2 at roundoff
    assert s["max_augmented_pos"] <= 1e-12 * H[0]         # Theorem 1 at roundoff


def test_iqn_ils_reaches_roundoff_with_fewer_calls_than_picard():
    """Interface quasi-Newton (IQN-ILS) on Table I: at K = 3 it is at the monolithic answer to
    roundoff, where Jacobi and Gauss-Seidel iterations need K = 10 and 5."""
    import wavecosim as wc
    table = wc.compare(masters=["jacobi-iter", "iqn-ils"], Ks=[3], T=2.0, certificates=False)
    errors = {r["master"]: r["max_error"] for r in table.rows}
    assert errors["iqn-ils"] < 1e-12 < errors["jacobi-iter"]
    assert table.rows[0]["doStep"] == table.rows[1]["doStep"]


def test_aitken_relaxes_by_the_secant_of_the_residuals():
    """Aitken's factor follows w_k = -w_{k-1} <r_{k-1}, r_k - r_{k-1}> / |r_k - r_{k-1}|^2."""
    import numpy as np
    from wavecosim.masters.quasi_newton import INITIAL_RELAXATION, AitkenMaster
    m = AitkenMaster.__new__(AitkenMaster)
    m.restart()
    y0, y1 = np.array([0.0, 0.0]), np.array([1.0, 2.0])
    first = m.update(y0, y1)
    assert np.allclose(first, INITIAL_RELAXATION * y1)
    r0, r1 = y1 - y0, np.array([0.3, 0.1]) - first
    second = m.update(first, np.array([0.3, 0.1]))
    w = -INITIAL_RELAXATION * (r0 @ (r1 - r0)) / ((r1 - r0) @ (r1 - r0))
    assert np.allclose(second, first + w * r1)
