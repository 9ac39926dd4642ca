"""master/certificates.py and the observers that use it, on the real Table I FMUs."""
import numpy as np
import pytest

from wavecosim.certificates import augmented_residual, fne_margins
from wavecosim.config import load_scenario
from wavecosim.scene import build_scene
from wavecosim.waves import port_energy


@pytest.fixture(scope="module")
def frozen_B():
    """LinearSide of Table I frozen at t = 0: its frozen map is affine, b = rho a + c."""
    scene = build_scene(load_scenario())
    B = scene.subsystems[1]
    B.freeze(0, 0.0)
    yield B
    scene.close()


def test_fne_margin_of_an_affine_map_is_rho_minus_rho_squared(frozen_B):
    rho = frozen_B.query([1.0])[0] - frozen_B.query([0.0])[0]
    margin = fne_margins(frozen_B, [0.3], pairs=6, rng=np.random.default_rng(0), scale=0.5, dt=0.01)
    frozen_B.thaw()
    assert margin == pytest.approx(rho - rho * rho, rel=1e-6)
    assert 0 < rho < 1


def test_augmented_residual_is_storage_plus_fejer_minus_supply():
    u0, uK, u_star = [1.0, 2.0], [0.5, 1.0], [0.0, 0.0]
    a, b = [3.0, -1.0], [2.0, 0.5]
    fejer = 0.5 * (0.25 + 1.0) - 0.5 * (1.0 + 4.0)
    assert augmented_residual(0.7, u0, uK, u_star, a, b) == pytest.approx(0.7 + fejer - port_energy(a, b))


def test_port_energy_of_waves_is_the_power_integral():
    """1/2(|a|^2 - |b|^2) with discrete waves equals dt e f (eqs. 3-5)."""
    from wavecosim.waves import waves
    a, b = waves(2.0, -0.7, gamma=3.0, dt=0.01)
    assert port_energy([a], [b]) == pytest.approx(0.01 * 2.0 * -0.7, rel=1e-12)
