"""Shared helpers of the test modules: strict compiler flags and the constrained systems that
several stages' tests use (imported as ``from helpers import ...``; tests/ is on pytest's path)."""

import numpy as np
import sympy as sp

import lagcodegen as lcg
from lagcodegen.theory.constraints import ConstrainedSystem

STRICT_CFLAGS = ["-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic"]
STRICT_FFLAGS = ["-Wall", "-Wextra", "-std=f2008", "-Werror"]

#: A two-link arm whose elbow j2 mimics the shoulder j1 (q2 = 0.5 q1 + 0.1), both revolute (as
#: Pinocchio's mimic joints must be), the shoulder limited to +-0.3 rad.
MIMIC_ARM = """<robot name="mimic_arm"><link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 1 0"/>
    <limit lower="-0.3" upper="0.3" effort="1" velocity="1"/></joint>
  <link name="a"><inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 -1"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="j1" multiplier="0.5" offset="0.1"/></joint>
  <link name="b"><inertial><origin xyz="0 0 -0.5"/><mass value="1.5"/>
    <inertia ixx="0.01" iyy="0.03" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""

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


