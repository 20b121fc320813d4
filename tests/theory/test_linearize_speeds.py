"""Linearization of models with generalized speeds about moving states (quaternion joints, in
tangent coordinates that move with the state), checked against textbook results: a free rigid
body spinning about its principal axes (Euler's equations), the sleeping top (the fast-top
condition and its two precession frequencies) and the same top on Z-Y-X angles."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import ModelError

INERTIA = (1.0, 2.0, 4.0)  # I1 < I2 < I3
MASS, LENGTH, A, C, G = 1.5, 0.4, 0.02, 0.05, 9.81  # the top: mass, pivot to centre of mass, inertias, gravity


def free_body():
    m = lcg.Model("spinner")
    m.link("body", joint=lcg.Joint.spherical("ball"), mass=1.0, inertia=INERTIA)
    return lcg.derive(m)


def top(rotation, axis="z"):
    """A heavy symmetric top on a ball joint at the origin, its axis along the body's ``axis``."""
    m = lcg.Model(f"top_{axis}_{rotation.lower()}")
    m.gravity(G)
    com = (0, 0, LENGTH) if axis == "z" else (LENGTH, 0, 0)
    inertia = (A, A, C) if axis == "z" else (C, A, A)
    m.link("body", joint=lcg.Joint.spherical("ball", rotation=rotation), mass=MASS, com=com, inertia=inertia)
    return lcg.derive(m)


def contains(eigenvalues, expected, tol=1e-10):
    return all(np.min(np.abs(eigenvalues - x)) <= tol * max(1.0, abs(x)) for x in expected)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_free_body_spinning_about_a_principal_axis(axis):
    """About axes 1 and 3 (least and largest moment) the perturbed spin oscillates at
    w sqrt((Ij - Ii)(Ik - Ii) / (Ij Ik)); about axis 2 it grows at w sqrt((I2 - I1)(I3 - I2) / (I1 I3));
    the tangent coordinates, turning with the body (H theta = theta x w0), add +-i w."""
    w = 1.7
    v0 = np.zeros(3)
    v0[axis] = w
    lin = lcg.linearize(free_body(), q0=[0, 0, 0, 1], v0=v0)
    assert lin.reduced and lin.H.shape == (3, 3)
    assert np.allclose(lin.H @ [0.1, -0.2, 0.3], np.cross([0.1, -0.2, 0.3], v0), atol=1e-14)
    i, j, k = axis, (axis + 1) % 3, (axis + 2) % 3
    rate = (INERTIA[j] - INERTIA[i]) * (INERTIA[k] - INERTIA[i]) / (INERTIA[j] * INERTIA[k])
    ev = lin.eigenvalues
    if axis == 1:  # the middle axis: rate < 0, a real pair
        expected = [w * np.sqrt(-rate), -w * np.sqrt(-rate)]
        assert not lin.stable()
    else:
        expected = [1j * w * np.sqrt(rate), -1j * w * np.sqrt(rate)]
        assert lin.stable()
    assert contains(ev, expected + [1j * w, -1j * w, 0.0])


@pytest.mark.parametrize("spin", [60.0, 40.0])
def test_sleeping_top_quaternion_agrees_with_classical_and_zyx(spin):
    """A top spinning at s about the vertical: its axis precesses at the roots w of
    I w^2 - C s w + m g l = 0 (I about the pivot), real (stable) iff C^2 s^2 > 4 I m g l (the
    fast top; s = 60 is fast, 40 is not); in the frame turning with the body they are w - s.
    The same top on Z-Y-X angles (pitch 0, non-singular) gives the same eigenvalues."""
    inertia = A + MASS * LENGTH ** 2
    roots = np.roots([inertia, -C * spin, MASS * G * LENGTH])
    expected = [1j * (r - spin) for r in roots] + [-1j * (np.conj(r) - spin) for r in roots]
    quat = lcg.linearize(top("quaternion"), q0=[0, 0, 0, 1], v0=[0, 0, spin])
    euler = lcg.linearize(top("ZYX"), q0=[0, 0, 0], v0=[spin, 0, 0])
    assert contains(quat.eigenvalues, expected)
    assert contains(quat.eigenvalues, euler.eigenvalues, 1e-9) and contains(euler.eigenvalues, quat.eigenvalues, 1e-9)
    fast = C ** 2 * spin ** 2 > 4 * inertia * MASS * G * LENGTH
    assert fast == (spin == 60.0) and quat.stable() == fast


def test_precessing_top_in_body_speeds_is_refused_zyx_gives_the_nutation_frequency():
    """Steady precession at tilt beta: m g l = W (C w3 - I W cos beta), nutation at
    sqrt((C w3 - 2 I W cos beta)^2 + (I W sin beta)^2) / I (I about the pivot). On Z-Y-X angles
    (pitch -0.5, the axis along body x) the linearization gives it; in body-frame speeds the
    speeds turn with the spin, so the frozen coefficients are refused by name."""
    inertia = A + MASS * LENGTH ** 2
    pitch, w3 = -0.5, 60.0
    cb, sb = -np.sin(pitch), np.cos(pitch)
    W = (C * w3 - np.sqrt(C ** 2 * w3 ** 2 - 4 * inertia * cb * MASS * G * LENGTH)) / (2 * inertia * cb)
    euler = lcg.linearize(top("ZYX", axis="x"), q0=[0, pitch, 0], v0=[W, 0, w3 + W * np.sin(pitch)])
    assert np.max(np.abs(euler.a0)) < 1e-10
    nutation = np.hypot(C * w3 - 2 * inertia * W * cb, inertia * W * sb) / inertia
    assert contains(euler.eigenvalues, [1j * nutation, -1j * nutation])
    q0 = [0, np.sin(pitch / 2), 0, np.cos(pitch / 2)]  # the same attitude as a quaternion
    with pytest.raises(ModelError, match="not a steady motion in these speeds"):
        lcg.linearize(top("quaternion", axis="x"), q0=q0, v0=[w3, 0, W * np.cos(pitch)])


def test_generalized_speeds_linearize_refusals():
    with pytest.raises(ModelError, match="symbolic=True takes models whose speeds"):
        lcg.linearize(free_body(), q0=[0, 0, 0, 1], symbolic=True)
    with pytest.raises(ModelError, match="independent and a0 are for constrained systems"):
        lcg.linearize(free_body(), q0=[0, 0, 0, 1], a0=[0, 0, 0])
    with pytest.raises(ModelError, match="tol must be a number"):
        lcg.linearize(free_body(), q0=[0, 0, 0, 1], v0=[1, 0, 0], tol=2)
