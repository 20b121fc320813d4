"""Shared helpers of the test modules: strict compiler flags and the constrained systems that
several stages' tests use (imported as ``from helpers import ...``; tests/ is on pytest's path)."""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem

STRICT_CFLAGS = ["-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"]
STRICT_FFLAGS = ["-Wall", "-Wextra", "-std=f2008", "-Werror"]

G = 9.81
TH0 = 1.0  # initial pendulum angle (rad)


# ---------------------------------------------------------------------- systems
def cartesian_pendulum(name="cpend"):
    """Bob at (x, y) with x^2 + y^2 = l^2 (eq. 4.1). A = (2x, 2y): the rod tension is -2 l lambda."""
    m = lcg.Model(name)
    x, y = m.coordinates("x y")
    l, g, mass = m.parameters(l=1.0, g=G, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x ** 2 + y ** 2 - l ** 2])


def atwood(name="atwood"):
    """Two masses on a string over a massless pulley; x1, x2 measured downwards, x1 + x2 = L."""
    m = lcg.Model(name)
    x1, x2 = m.coordinates("x1 x2")
    m1, m2, g, L = m.parameters(m1=3.0, m2=1.0, g=G, L=2.0)
    m.particle("b1", m1, (0, -x1))
    m.particle("b2", m2, (1, -x2))
    m.gravity(g)
    return ConstrainedSystem(m, holonomic=[x1 + x2 - L])


def knife_edge(name="knife"):
    """Knife edge on an inclined plane: no velocity across the blade, sin(th) x' - cos(th) y' = 0."""
    m = lcg.Model(name)
    x, y, th = m.coordinates("x y theta")
    mass, Iz, g, al = m.parameters(m=1.0, Iz=0.1, g=G, alpha=0.3)
    m.kinetic_energy(mass / 2 * (m.dot(x) ** 2 + m.dot(y) ** 2) + Iz / 2 * m.dot(th) ** 2)
    m.potential_energy(-mass * g * sp.sin(al) * x)
    return ConstrainedSystem(m, nonholonomic=[([sp.sin(th), -sp.cos(th), 0], 0)])


def pendulum_q0(th=TH0, l=1.0):
    return [l * np.sin(th), -l * np.cos(th)]


def mixed_system():
    """Holonomic and nonholonomic rows together: a knife edge held on the line y = x sin(t)/4... plus events."""
    cs = knife_edge(name="mixed")
    m = cs.model
    x, y, th = m.coords
    return ConstrainedSystem(m, holonomic=[y - x * sp.sin(m.t) / 4],
                             nonholonomic=[([sp.sin(th), -sp.cos(th), 0], 0)], inequalities=[3 - x])


