"""Scattering transform (paper eqs. 3-5): waves from power variables and back.

Discrete waves carry sqrt(dt), so 1/2 (|a|^2 - |b|^2) is the energy through the port in one step.
"""
import math


def waves(e, f, gamma, dt=1.0):
    """(a, b) = sqrt(dt) (e +- gamma f) / sqrt(2 gamma), eq. (3)."""
    k = math.sqrt(dt / (2.0 * gamma))
    return k * (e + gamma * f), k * (e - gamma * f)


def power_variables(a, b, gamma, dt=1.0):
    """(e, f) from discrete waves, eq. (4)."""
    return math.sqrt(gamma / (2.0 * dt)) * (a + b), (a - b) / math.sqrt(2.0 * gamma * dt)


def port_energy(a, b):
    """1/2 (|a|^2 - |b|^2): energy entering the port over the step, eq. (5)."""
    return 0.5 * (sum(x * x for x in a) - sum(x * x for x in b))
