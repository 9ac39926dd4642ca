"""Dirac structure E e + F f = 0 compiled to the orthogonal wave map P (paper eqs. 7-10, Remark 1)."""
import numpy as np
import pytest

from wavecosim.core import interconnection as ic
from wavecosim.errors import CouplingError
from wavecosim.core.waves import port_energy, power_variables, waves


def test_two_port_coupling_compiles_to_the_swap_exactly():
    for gamma in (0.01, 0.4, 5.0, 100.0):
        w = ic.compile_wave_map(*ic.equal_effort_opposite_flow(1), [gamma, gamma])
        assert w.P.tolist() == [[0.0, 1.0], [1.0, 0.0]]
        assert np.allclose(w.J_L, np.array([[2, 1], [1, 2]]) / 3.0, atol=1e-15)


def test_vector_port_swap_is_block_permutation():
    w = ic.compile_wave_map(*ic.equal_effort_opposite_flow(2), [0.4] * 4)
    expected = np.block([[np.zeros((2, 2)), np.eye(2)], [np.eye(2), np.zeros((2, 2))]])
    assert np.array_equal(np.abs(w.P), expected)


@pytest.mark.parametrize("structure", [
    ic.zero_junction(3), ic.one_junction(4), ic.transformer(2.5), ic.gyrator(0.7),
    ic.equal_effort_opposite_flow(3), ic.free_end(), ic.clamped_end()])
def test_lossless_structures_give_orthogonal_maps_for_any_impedances(structure):
    E, F = structure
    rng = np.random.default_rng(3)
    gammas = rng.uniform(0.05, 20.0, E.shape[0])
    w = ic.compile_wave_map(E, F, gammas)
    assert w.orthogonality_residual < 1e-12
    assert np.allclose(w.P.T @ w.P, np.eye(E.shape[0]), atol=1e-12)
    # the waves a = P b satisfy the physical constraints E e + F f = 0 channel by channel
    b = rng.standard_normal(E.shape[0])
    a = w.P @ b
    e = np.sqrt(gammas / 2.0) * (a + b)
    f = (a - b) / np.sqrt(2.0 * gammas)
    assert np.allclose(E @ e + F @ f, 0.0, atol=1e-12)
    assert abs(e @ f) < 1e-12  # lossless: no net power


def test_junction_resolvent_is_inverse_of_2I_minus_P():
    w = ic.compile_wave_map(*ic.zero_junction(5), [0.4] * 5)
    assert np.allclose(w.J_L @ (2 * np.eye(5) - w.P), np.eye(5), atol=1e-14)


def test_lossy_coupling_is_rejected_with_its_residual():
    E = np.array([[1.0, -1.0], [0.0, 0.0]])
    F = np.array([[0.5, 0.0], [1.0, 1.0]])  # e_A - e_B + 0.5 f_A = 0: a resistor in the link
    with pytest.raises(CouplingError, match="not lossless"):
        ic.compile_wave_map(E, F, [0.4, 0.4])


def test_rank_deficient_coupling_is_rejected():
    E = np.array([[1.0, -1.0], [2.0, -2.0]])
    F = np.zeros((2, 2))
    with pytest.raises(CouplingError, match="full rank"):
        ic.compile_wave_map(E, F, [0.4, 0.4])


def test_channels_must_be_connected_exactly_once():
    E, F = ic.equal_effort_opposite_flow(1)
    with pytest.raises(CouplingError, match="not connected"):
        ic.assemble([("c", E, F, [0, 1])], 3)
    with pytest.raises(CouplingError, match="already connected"):
        ic.assemble([("c", E, F, [0, 1]), ("d", E, F, [1, 2])], 3)


def test_scattering_round_trip_conserves_power():
    rng = np.random.default_rng(0)
    for _ in range(100):
        e, f, gamma, dt = rng.normal() * 50, rng.normal() * 3, rng.uniform(0.01, 100), rng.uniform(1e-4, 0.1)
        a, b = waves(e, f, gamma, dt)
        e2, f2 = power_variables(a, b, gamma, dt)
        assert e2 == pytest.approx(e, rel=1e-12, abs=1e-12)
        assert f2 == pytest.approx(f, rel=1e-12, abs=1e-12)
        assert port_energy([a], [b]) == pytest.approx(dt * e * f, rel=1e-10, abs=1e-12)


def test_gyrator_between_rlc_and_motor_is_a_signed_swap():
    """The coupling documented in rlc_circuit/config.h: u = Km omega, tau = -Km i with
    gamma_motor = Km^2 / gamma_rlc compiles to a_rlc = -b_motor, a_motor = b_rlc (lossless)."""
    km, g_rlc = 0.1, 1.0
    (suffix, E, F), = ic.COUPLINGS["gyrator"](type("C", (), {"type": "gyrator", "ratio": km}), [[0], [1]], "test")
    w = ic.compile_wave_map(E, F, [g_rlc, km ** 2 / g_rlc])
    assert np.allclose(w.P, [[0.0, -1.0], [1.0, 0.0]], rtol=0, atol=1e-12)
    rng = np.random.default_rng(3)
    i, omega = rng.standard_normal(2)
    e, f = np.array([km * omega, -km * i]), np.array([i, omega])     # (u, i) and (tau, omega)
    assert abs(e @ f) < 1e-15 and np.allclose(E @ e + F @ f, 0.0, atol=1e-15)
