"""Standard mechanical systems, ready-made models for examples, tests and benchmarks."""

from __future__ import annotations

import sympy as sp

from .model import Model


def pendulum(name: str = "pendulum") -> Model:
    """Simple pendulum: bob of mass m on a massless rod of length l, angle theta from the downward vertical."""
    m = Model(name)
    th, = m.coordinates("theta")
    l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (l * sp.sin(th), -l * sp.cos(th)))
    m.gravity(g)
    return m


def double_pendulum(name: str = "double_pendulum") -> Model:
    """Planar double pendulum of two point masses; angles from the downward vertical."""
    m = Model(name)
    th1, th2 = m.coordinates("theta1 theta2")
    l1, l2, m1, m2, g = m.parameters(l1=1.0, l2=1.0, m1=1.0, m2=1.0, g=9.81)
    x1, y1 = l1 * sp.sin(th1), -l1 * sp.cos(th1)
    m.particle("bob1", m1, (x1, y1))
    m.particle("bob2", m2, (x1 + l2 * sp.sin(th2), y1 - l2 * sp.cos(th2)))
    m.gravity(g)
    return m


def n_link_pendulum(n: int, name: str | None = None, shared_parameters: bool = True) -> Model:
    """Planar chain of n point masses on massless rods (the classic n-link pendulum).

    With ``shared_parameters`` all links share l and m; otherwise each link k has l<k>, m<k>.
    """
    m = Model(name or f"pendulum{n}")
    qs = m.coordinates([f"q{k}" for k in range(1, n + 1)])
    g, = m.parameters(g=9.81)
    if shared_parameters:
        l, mass = m.parameters(l=1.0, m=1.0)
    x = y = sp.Integer(0)
    for k, q in enumerate(qs, start=1):
        if not shared_parameters:
            l, mass = m.parameters(**{f"l{k}": 1.0, f"m{k}": 1.0})
        x, y = x + l * sp.sin(q), y - l * sp.cos(q)
        m.particle(f"bob{k}", mass, (x, y))
    m.gravity(g)
    return m


def damped_driven_oscillator(name: str = "oscillator") -> Model:
    """Mass on a spring with viscous damping and a harmonic driving force:
    m x'' + c x' + k x = F0 cos(w t)."""
    m = Model(name)
    x, = m.coordinates("x")
    mass, k, c, F0, w = m.parameters(m=1.0, k=4.0, c=0.4, F0=1.0, w=1.5)
    m.particle("mass", mass, (x, 0))
    m.spring("mass", (0, 0), k)
    m.damper("mass", c)
    m.generalized_force(x, F0 * sp.cos(w * m.t), label="drive")
    return m


def central_potential(name: str = "central", exponent: int = -1) -> Model:
    """Particle in a central potential V = -k/r (exponent -1) or V = k r^exponent/exponent, polar coordinates."""
    m = Model(name)
    r, phi = m.coordinates("r phi")
    mass, k = m.parameters(m=1.0, k=1.0)
    m.particle("body", mass, (r * sp.cos(phi), r * sp.sin(phi)))
    if exponent == -1:
        m.potential_energy(-k / r, label="gravity")
    else:
        m.potential_energy(k * r**exponent / exponent, label="central")
    return m
