"""Standard mechanical systems, ready-made models for examples, tests and benchmarks."""

from __future__ import annotations

import math

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


def forced_oscillator(name: str = "forced_oscillator", m: float = 1.0, k: float = 4.0, c: float = 0.4) -> Model:
    """Mass on a spring with viscous damping driven by a force F given as an input signal (a table
    at run time: ``simulate(..., inputs={"F": lcg.Table(...)})``): m x'' + c x' + k x = F.
    Outputs "force" (F) and "spring" (k x)."""
    model = Model(name)
    x, = model.coordinates("x")
    mass, stiffness, damping = model.parameters(m=m, k=k, c=c)
    force = model.input("F")
    model.kinetic_energy(mass * model.dot(x) ** 2 / 2)
    model.potential_energy(stiffness * x ** 2 / 2)
    model.dissipation(damping * model.dot(x) ** 2 / 2)
    model.generalized_force(x, force)
    model.output("force", force)
    model.output("spring", stiffness * x)
    return model


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

def spherical_pendulum(name: str = "spherical_pendulum") -> Model:
    """Bob of mass m on a massless rod of length l, free to swing in 3-D.

    theta is measured from the downward vertical, phi is the azimuth:
    x = (l sin(theta) cos(phi), l sin(theta) sin(phi), -l cos(theta)), gravity along -z.
    phi is ignorable (sec. 3.4): its momentum m l^2 sin^2(theta) phi' is an integral of motion.
    """
    m = Model(name)
    th, ph = m.coordinates("theta phi")
    mass, l, g = m.parameters(m=1.0, l=1.0, g=9.81)
    m.particle("bob", mass, (l * sp.sin(th) * sp.cos(ph), l * sp.sin(th) * sp.sin(ph), -l * sp.cos(th)))
    m.gravity(g)
    return m


def bead_on_spinning_hoop(name: str = "hoop") -> Model:
    """Bead of mass m on a hoop of radius a spinning at the constant rate w about the vertical axis.

    theta is the bead's angle from the bottom of the hoop:
    x = (a sin(theta) cos(w t), a sin(theta) sin(w t), -a cos(theta)), gravity along -z.
    L = m a^2/2 (theta'^2 + w^2 sin^2(theta)) + m g a cos(theta): no coordinate is ignorable,
    and h = T_2 - T_0 + V (eq. 3.7) is conserved while T + V is not.
    """
    m = Model(name)
    th, = m.coordinates("theta")
    mass, a, g, w = m.parameters(m=1.0, a=1.0, g=9.81, w=5.0)
    t = m.t
    m.particle("bead", mass, (a * sp.sin(th) * sp.cos(w * t), a * sp.sin(th) * sp.sin(w * t), -a * sp.cos(th)))
    m.gravity(g)
    return m

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


def spring_chain(n: int = 20, ratio: float = 1e6, zeta: float = 1.0, name: str | None = None):
    """N unit masses in a line between two walls: soft springs k = 1 (walls, and between
    dimers) alternating with stiff springs ratio * k inside each dimer (masses 1-2, 3-4, ...),
    each stiff spring with a parallel damper c = zeta * 2 sqrt(ratio k m / 2) (zeta = 1:
    critically damped relative motion of a dimer). Coordinates x_i: displacements.

    Stiffness: the dimers' internal modes have rates ~ sqrt(2 ratio) (undamped) or ~ c
    (damped), the chain's slow modes ~ 0.1..1: a stiff system for large ratios; the
    Jacobian is banded (bandwidths 2, 3 in the interleaved order) and M is diagonal.
    """
    m = Model(name or f"chain{n}")
    xs = m.coordinates([f"x{i}" for i in range(1, n + 1)])
    c_value = zeta * 2.0 * math.sqrt(ratio * 0.5)
    k, r, c, mass = m.parameters(k=1.0, ratio=float(ratio), c=c_value, m=1.0)
    for i, x in enumerate(xs, start=1):
        m.particle(f"m{i}", mass, (x, 0))
    m.spring("m1", (0, 0), k)
    for i in range(1, n):
        if i % 2 == 1:
            m.spring(f"m{i}", f"m{i + 1}", k * r)
            m.damper(f"m{i}", c, f"m{i + 1}")
        else:
            m.spring(f"m{i}", f"m{i + 1}", k)
    m.spring(f"m{n}", (0, 0), k)
    return m
