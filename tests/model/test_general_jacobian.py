"""The analytic Jacobian df/dy of models with generalized speeds (y = (q, v, z)): expanded and
tangent forms, C and Fortran, against central differences of the compiled right-hand side, and
BDF runs with it against runs on CVODE's difference quotients."""

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.api import auto_jacobian, build_code
from lagcodegen.codegen.languages import generate_code
from lagcodegen.formulation.scene import Scene

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def tumbler():
    m = lcg.Model("gj_tumbler")
    m.link("body", joint=lcg.Joint.spherical("ball"), mass=1.0, inertia=(1.0, 2.0, 3.0))
    return m


def floating_arm():
    return lcg.urdf.load(EXAMPLES / "ur_like_arm.urdf", floating=True)


def free_flyer_with_spring():
    """A free body on a quaternion joint with a linear spring to the origin and a torsion-free
    pendulum hanging from it: gravity, a potential and a revolute joint after the free one."""
    m = lcg.Model("gj_flyer")
    m.link("base", joint=lcg.Joint.free("root"), mass=2.0, inertia=(1.0, 1.5, 2.0))
    m.link("arm", parent="base", joint=lcg.Joint.revolute("elbow"), mass=0.5, inertia=(0.1, 0.2, 0.3))
    x, y, z = (sp.Symbol(f"root_{a}") for a in "xyz")
    k, = m.parameters(k=3.0)
    m.potential_energy(k / 2 * (x ** 2 + y ** 2 + z ** 2))
    return m


def polar(damped=False):
    """A closed-form model of its own speeds: polar coordinates with u1 = r', u2 = r theta'."""
    m = lcg.Model("gj_polar" + ("_d" if damped else ""))
    r, th = m.coordinates("r theta")
    k, mass, c = m.parameters(k=3.0, m=1.5, c=0.2)
    m.particle("p", mass, (r * sp.cos(th), r * sp.sin(th)))
    m.potential_energy(k / 2 * (r - 1) ** 2 + sp.cos(th) * r ** 2 / 5)
    u1, u2 = sp.symbols("u1 u2")
    m.generalized_speeds(["u1", "u2"], {r: u1, th: u2 / r})
    if damped:  # Rayleigh dissipation in q' (the kinematics inside F)
        m.dissipation(c / 2 * sp.Symbol("r_dot") ** 2 * r)
    return m


def compiled(model, form, lang="c", tag=""):
    eom = lcg.derive(model)
    scene = Scene(eom, jacobian=True, jacobian_form=form, prefix=f"{model.name}_{form}_{lang}{tag}",
                  outputs=["energy"] if form else [])
    return build_code(generate_code(scene, lang))


def random_state(cm, eom_model, rng):
    nq, nv = eom_model.nq, eom_model.nv
    q = rng.uniform(-1, 1, nq)
    names = [c.name for c in eom_model.coords]
    for i, n in enumerate(names):  # quaternions: unit 4-vectors
        if n.endswith("_qx"):
            q[i:i + 4] /= np.linalg.norm(q[i:i + 4])
        if n == "r":
            q[i] = 1.3
    return np.r_[q, rng.normal(size=nv), np.zeros(cm.ny - nq - nv)]


def central(cm, y, h=3e-3):
    """Five-point central differences of the compiled right-hand side (error O(h^4))."""
    J = np.empty((cm.ny, cm.ny))
    for j in range(cm.ny):
        e = np.zeros(cm.ny)
        e[j] = h * max(1.0, abs(y[j]))
        J[:, j] = (8 * (cm.rhs(0.3, y + e) - cm.rhs(0.3, y - e))
                   - (cm.rhs(0.3, y + 2 * e) - cm.rhs(0.3, y - 2 * e))) / (12 * e[j])
    return J


CASES = [("tumbler", tumbler, "tangent"), ("flyer", free_flyer_with_spring, "tangent"),
         ("arm", floating_arm, "tangent"), ("polar", polar, "expanded"), ("polar", polar, "tangent"),
         ("polar_d", lambda: polar(True), "expanded"), ("polar_d", lambda: polar(True), "tangent")]


@pytest.mark.parametrize("lang", ["c", "fortran"])
@pytest.mark.parametrize("name, make, form", CASES)
def test_jacobian_matches_central_differences(name, make, form, lang):
    model = make()
    cm = compiled(model, form, lang)
    rng = np.random.default_rng(3)
    for _ in range(3):
        y = random_state(cm, model, rng)
        J = cm.jac(0.3, y)
        D = central(cm, y)
        scale = max(1.0, np.abs(D).max())
        assert np.abs(J - D).max() < 1e-8 * scale, (np.abs(J - D).max(), scale)
        # the pattern holds every nonzero entry
        pattern = cm.code.jac_pattern
        assert not np.any((np.abs(J) > 0) & ~pattern)


@pytest.mark.parametrize("name, make, form", [("flyer", free_flyer_with_spring, "tangent"),
                                              ("polar_d", lambda: polar(True), "expanded"),
                                              ("polar_d", lambda: polar(True), "tangent")])
def test_general_jacobian_sources_compile_strictly(tmp_path, name, make, form):
    import subprocess
    from helpers import STRICT_CFLAGS
    model = make()
    code = generate_code(Scene(lcg.derive(model), jacobian=True, jacobian_form=form, prefix=f"strict_{name}_{form}"))
    for file, text in code.files.items():
        (tmp_path / file).write_text(text)
    for file in code.files:
        if file.endswith(".c"):
            proc = subprocess.run(["cc", *STRICT_CFLAGS, "-O0", "-c", file, "-o", "x.o"], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=600)
            assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("name, make, q0, v0", [
    ("flyer", free_flyer_with_spring, [0.5, -0.2, 0.1, 0.1, 0.2, 0.3, 0.9, 0.4], [0.3, -0.2, 0.5, 0.4, -0.3, 0.8, 1.0]),
    ("arm", floating_arm, np.r_[0, 0, 1.0, 0.1, 0.2, 0.0, 1.0, np.linspace(-0.5, 0.5, 6)],
     np.r_[0.3, -0.2, 0.5, 0.4, -0.3, 0.8, np.linspace(1, -1, 6)]),
    ("polar", polar, [1.2, 0.3], [0.1, 0.9])])
def test_bdf_with_the_analytic_jacobian_equals_difference_quotients(name, make, q0, v0):
    """jacobian=None turns the analytic Jacobian on for these models up to 8 coordinates
    (auto_jacobian); BDF runs with it agree with runs on CVODE's difference quotients to the
    tolerance, and both with Adams at a tight one."""
    model = make()
    q0 = np.asarray(q0, float)
    for i, c in enumerate(model.coords):  # a unit quaternion
        if c.name.endswith("_qx"):
            q0[i:i + 4] /= np.linalg.norm(q0[i:i + 4])
    # jacobian=None: on up to AUTO_JACOBIAN_MAX_N (8) coordinates, as for models in q'
    assert auto_jacobian(lcg.derive(model)) == (model.nq <= 8)
    a = lcg.compile_model(model, jacobian=None if model.nq <= 8 else True)
    b = lcg.compile_model(model, jacobian=False, prefix=f"{model.name}_dq")
    assert a.c_jac is not None and b.c_jac is None
    t = np.linspace(0, 2, 21)
    ra = a.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-9, atol=1e-10)
    rb = b.simulate(t, q0=q0, v0=v0, method="bdf", rtol=1e-9, atol=1e-10)
    ref = a.simulate(t, q0=q0, v0=v0, method="adams", rtol=1e-13, atol=1e-14)
    scale = max(1.0, np.abs(ref.y).max())
    assert np.abs(ra.y - ref.y).max() < 1e-6 * scale
    assert np.abs(rb.y - ref.y).max() < 1e-6 * scale
    assert np.abs(ra.y - rb.y).max() < 1e-6 * scale


def test_what_generalized_speeds_do_not_take_is_named():
    """The sparse Jacobian and the band linear solver (its order pairs q_i with q_i') are refused
    by name for models with generalized speeds."""
    from lagcodegen.errors import LagcodegenError, ModelError
    m = free_flyer_with_spring()
    with pytest.raises(ModelError, match="generalized speeds .* sparse Jacobian"):
        Scene(lcg.derive(m), sparse_jacobian=True)
    cm = lcg.compile_model(m)
    with pytest.raises(LagcodegenError, match="generalized speeds .* band linear solver"):
        cm.simulate(np.linspace(0, 1, 3), q0=[0, 0, 0, 0, 0, 0, 1, 0], v0=np.zeros(7), method="bdf",
                    linear_solver="band")


@pytest.mark.parametrize("lang", ["c", "fortran"])
def test_expanded_jacobian_in_program_form(monkeypatch, lang):
    """A right-hand side printed in program form (forced here: PROGRAM_MIN_OPS = 0) prints the
    expanded Jacobian in pieces too (G over the (q, v) columns, Z the kinematic and quadrature
    rows): the same values as the central differences."""
    from lagcodegen.codegen import c as cgen, program
    monkeypatch.setattr(cgen, "PROGRAM_MIN_OPS", 0)
    monkeypatch.setattr(program, "PROGRAM_MIN_OPS", 0)
    model = polar(True)
    code = generate_code(Scene(lcg.derive(model), jacobian=True, jacobian_form="expanded",
                               prefix=f"gj_polar_pieces_{lang}"), lang)
    assert "jacobian0" in "".join(code.files.values())  # the pieces are there
    cm = build_code(code)
    rng = np.random.default_rng(5)
    for _ in range(3):
        y = random_state(cm, model, rng)
        D = central(cm, y)
        assert np.abs(cm.jac(0.3, y) - D).max() < 1e-8 * max(1.0, np.abs(D).max())


@pytest.mark.parametrize("lang", ["c", "fortran"])
@pytest.mark.parametrize("form", ["expanded", "tangent"])
def test_jacobian_with_a_quadrature_state(lang, form):
    """A quadrature state z' = rate(q, q', v) after (q, v) (rows nq + nv ..; the quadrature
    enters no rate): its row of df/dy, with q' inside the rate standing for the kinematics."""
    import dataclasses
    import symengine as se
    model = polar()
    eom = lcg.derive(model)
    rate = se.Symbol("theta_dot") ** 2 * se.Symbol("r") + se.Symbol("u1") * se.sin(se.Symbol("theta"))
    eom = dataclasses.replace(eom, quadratures=[("work", rate)])
    cm = build_code(generate_code(Scene(eom, jacobian=True, jacobian_form=form,
                                        prefix=f"gj_polar_quad_{form}_{lang}"), lang))
    assert cm.ny == 5
    rng = np.random.default_rng(7)
    for _ in range(3):
        y = random_state(cm, model, rng)
        y[4] = rng.normal()
        J, D = cm.jac(0.3, y), central(cm, y)
        assert np.abs(J - D).max() < 1e-8 * max(1.0, np.abs(D).max())
        assert np.abs(J[4, :4]).min() > 0  # the rate depends on every state of (q, v)
        assert not np.any((np.abs(J) > 0) & ~cm.code.jac_pattern)
