"""Models for the energy and force checks: rotating frames, a charge in E and B, a damped pendulum.

(The bead on a spinning hoop lives in :mod:`lagcodegen.systems_extra`.)
"""

from __future__ import annotations

import sympy as sp

from .model import Model
from .systems import pendulum


def rotating_frame_particle(name: str = "rotating_frame") -> Model:
    """A particle in a harmonic well, written in coordinates (X, Y) of a frame turning at rate w.

    x = X cos(w t) - Y sin(w t), y = X sin(w t) + Y cos(w t); V = k/2 (X^2 + Y^2).
    T = m/2 (X'^2 + Y'^2) + m w (X Y' - Y X') + m w^2 (X^2 + Y^2)/2: T1 != 0 (eq. 2.2).
    """
    m = Model(name)
    X, Y = m.coordinates("X Y")
    mass, w, k = m.parameters(m=1.0, w=0.7, k=2.0)
    t = m.t
    m.particle("body", mass, (X * sp.cos(w * t) - Y * sp.sin(w * t), X * sp.sin(w * t) + Y * sp.cos(w * t)))
    m.potential_energy(k / 2 * (X**2 + Y**2), label="well")
    return m


def charged_particle(name: str = "charged", polar: bool = False) -> Model:
    """A charge e of mass m in the plane, uniform B along z and uniform E (parameter ``Ex``) along x.

    Generalized potential (eq. 3.4) U = e (phi - v . A) with phi = -E x and the symmetric gauge
    A = (-B y/2, B x/2, 0): U = -e E x - e B (x y' - y x')/2. Coordinates (x, y), or (r, theta)
    with x = r cos(theta), y = r sin(theta) when ``polar``.
    """
    m = Model(name)
    mass, e, B, E = m.parameters(m=1.0, e=1.0, B=1.0, Ex=0.0)
    if polar:
        r, th = m.coordinates("r theta")
        x, y = r * sp.cos(th), r * sp.sin(th)
    else:
        x, y = m.coordinates("x y")
    m.particle("charge", mass, (x, y))
    vx, vy = m.time_derivative(x), m.time_derivative(y)
    phi = -E * x
    A = (-B * y / 2, B * x / 2)
    m.generalized_potential(e * (phi - (vx * A[0] + vy * A[1])), label="electromagnetic")
    return m


def damped_pendulum(name: str = "damped_pendulum") -> Model:
    """Simple pendulum with a linear damper c on the bob: D = c/2 |v|^2 = c l^2 theta'^2 / 2 (eq. 3.15)."""
    m = pendulum(name)
    c, = m.parameters(c=0.3)
    m.damper("bob", c)
    return m
