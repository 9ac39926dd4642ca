"""Scattering transform (paper eqs. 3-5): the only place the wave formulas are written.

Discrete waves carry sqrt(dt), so 1/2 (|a|^2 - |b|^2) is the energy through the port in one step.
"""
import math

from ..kernel.linalg import dot


def wave_scale(gamma, dt=1.0):
    """k = sqrt(dt / (2 gamma)), so that a = k (e + gamma f) and b = k (e - gamma f)."""
    return math.sqrt(dt / (2.0 * gamma))


def waves(e, f, gamma, dt=1.0):
    """(a, b) = sqrt(dt) (e +- gamma f) / sqrt(2 gamma), eq. (3)."""
    k = wave_scale(gamma, dt)
    return k * (e + gamma * f), k * (e - gamma * f)


def outgoing_wave(e, f, gamma, dt=1.0):
    """b of eq. (3) alone: the committed wave re-scattered to a new gamma."""
    return wave_scale(gamma, dt) * (e - gamma * f)


def power_variables(a, b, gamma, dt=1.0):
    """(e, f) from discrete waves, eq. (4)."""
    return math.sqrt(gamma / (2.0 * dt)) * (a + b), (a - b) / math.sqrt(2.0 * gamma * dt)


def port_energy(a, b):
    """1/2 (|a|^2 - |b|^2): energy entering the port(s) over the step, eq. (5); sums left to right."""
    return 0.5 * (dot(a, a) - dot(b, b))


def physical_port_energy(e, f, dt):
    """dt e.f: energy entering a port over the step from its stage effort and flow."""
    return dt * dot(e, f)
