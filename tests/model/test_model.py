"""Model inputs through the Python API: non-finite masses and parameters, negative masses, names
that would collide with the symbols lagcodegen invents."""

import math
import warnings

import numpy as np
import pytest
import sympy as sp

from lagcodegen import Model, ModelError, Scene, derive


def pendulum_model(name="p"):
    m = Model(name)
    th, = m.coordinates("theta")
    l, g = m.parameters(l=1.0, g=9.81)
    return m, th, l, g


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -math.inf, np.float64("nan"), sp.nan, sp.oo,
                                 sp.zoo, "sympy"])
def test_non_finite_mass_is_a_model_error_naming_the_body(bad):
    m, th, l, g = pendulum_model()
    mass = sp.Symbol("l") * sp.nan if bad == "sympy" else bad  # NaN inside an expression too
    with pytest.raises(ModelError, match="mass of body 'bob' is not finite"):
        m.particle("bob", mass, (l * sp.sin(th), -l * sp.cos(th)))
    assert not m.bodies and "bob" not in m.points  # nothing half declared


@pytest.mark.parametrize("kind", ["planar mass", "planar inertia", "rigid mass", "rigid inertia"])
def test_non_finite_body_mass_or_inertia_is_refused(kind):
    m = Model("bodies")
    x, = m.coordinates("x")
    nan = float("nan")
    if kind.startswith("planar"):
        with pytest.raises(ModelError, match=f"{kind.split()[1]} of body 'plate' is not finite"):
            m.planar_body("plate", nan if kind == "planar mass" else 1.0, math.inf if kind == "planar inertia" else 1.0,
                          (x, 0), 0)
    else:
        with pytest.raises(ModelError, match=f"{kind.split()[1]} of body 'box' is not finite"):
            inertia = (1, 1, nan) if kind == "rigid inertia" else (1, 1, 1)
            m.rigid_body("box", nan if kind == "rigid mass" else 1.0, inertia, (x, 0, 0), sp.eye(3))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf"), sp.nan, sp.oo])
def test_non_finite_parameter_is_a_model_error_naming_it(bad):
    m = Model("params")
    with pytest.raises(ModelError, match="parameter 'stiff'"):
        m.parameter("stiff", bad)
    with pytest.raises(ModelError, match="parameter 'k2'"):
        m.parameters(k2=bad)


def test_non_finite_scene_value_is_a_model_error_naming_the_parameter():
    m, th, l, g = pendulum_model()
    m.particle("bob", 1.0, (l * sp.sin(th), -l * sp.cos(th)))
    m.gravity(g)
    with pytest.raises(ModelError, match="parameter 'g'"):
        Scene(derive(m), runtime_parameters=["l"], values={"g": float("nan")})


def test_negative_mass_warns_naming_the_body():
    m, th, l, g = pendulum_model()
    with pytest.warns(UserWarning, match="mass of body 'bob' is negative"):
        m.particle("bob", -2.0, (l * sp.sin(th), -l * sp.cos(th)))
    m2, th2, l2, g2 = pendulum_model()
    mass, = m2.parameters(mass=-1.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a parameter: judged at derivation, with its default
        m2.particle("weight", mass, (l2 * sp.sin(th2), -l2 * sp.cos(th2)))
    m2.gravity(g2)
    with pytest.warns(UserWarning, match="mass of body 'weight' is negative.*-1.5"):
        derive(m2)


def test_positive_masses_do_not_warn():
    m, th, l, g = pendulum_model()
    mass, = m.parameters(mass=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m.particle("bob", mass, (l * sp.sin(th), -l * sp.cos(th)))
        m.gravity(g)
        derive(m)


@pytest.mark.parametrize("names", [["__acc0", "__acc1"], ["__qp0"], ["__mu0"], ["__x"]])
def test_names_of_generated_temporaries_are_refused(names):
    m = Model("temps")
    with pytest.raises(ModelError, match="starts with '__', which is reserved"):
        m.coordinates(names)
    with pytest.raises(ModelError, match="reserved"):
        m.parameter(names[0], 1.0)


@pytest.mark.parametrize("first, second, taken", [("x", "x_dot", "velocity"), ("x", "x_ddot", "acceleration"),
                                                   ("x_dot", "x", "velocity"), ("x_ddot", "x", "acceleration")])
def test_coordinate_named_like_another_coordinates_velocity_is_refused(first, second, taken):
    m = Model("dots")
    m.coordinates(first)
    with pytest.raises(ModelError, match=taken):
        m.coordinates(second)
    p = Model("dotparams")
    p.coordinates("x")
    with pytest.raises(ModelError, match="velocity of coordinate 'x'"):
        p.parameter("x_dot", 1.0)


class _CountingList(list):
    """A list that counts the loops over it (``for``, comprehensions, ``in``)."""

    loops = 0

    def __iter__(self):
        type(self).loops += 1
        return super().__iter__()

    def __contains__(self, item):
        type(self).loops += 1
        return super().__contains__(item)


def test_declaring_names_and_finding_coordinates_never_loop_over_the_coordinates():
    """Name checks and Model.index take constant time per call (the name set was rebuilt on
    every declaration and index scanned the list: 8000 coordinates in a model file took 62 s):
    once the model is known, declaring coordinates and parameters and finding coordinates by
    name loop over no list of coordinates; the checks still see every name."""
    m = Model("many")
    m.coordinates([f"q{i}" for i in range(2000)])
    m.coords = _CountingList(m.coords)  # replaced from outside: the names are read again once
    with pytest.raises(ModelError, match="'q5' is declared twice"):
        m.coordinate("q5")
    _CountingList.loops = 0
    m.coordinates([f"r{i}" for i in range(200)])
    m.parameters(**{f"k{i}": 1.0 for i in range(200)})
    assert [m.index(f"r{i}") for i in range(0, 200, 7)] == [2000 + i for i in range(0, 200, 7)]
    assert m.index(m.coords[17]) == 17
    with pytest.raises(ModelError, match=r"name 'r3_dot' is taken by the velocity of coordinate 'r3'"):
        m.parameter("r3_dot", 1.0)
    with pytest.raises(ModelError, match=r"name 'q7_ddot' is taken by the acceleration of coordinate 'q7'"):
        m.coordinate("q7_ddot")
    with pytest.raises(ModelError, match="'k3' is declared twice"):
        m.coordinate("k3")
    m.parameter("z_dot", 1.0)
    with pytest.raises(ModelError, match=r"coordinate 'z': 'z_dot' \(its velocity\) is already the name"):
        m.coordinate("z")
    assert _CountingList.loops == 0
    m.coords.append(sp.Symbol("s"))  # grown from outside (no speed): the names are read again
    m.speeds.append(sp.Symbol("s_dot"))
    with pytest.raises(ModelError, match="'s' is declared twice"):
        m.parameter("s", 1.0)
    assert m.index("s") == 2200
