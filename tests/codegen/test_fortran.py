"""Generated Fortran: strict gfortran, the same numbers as the C backend, the native driver."""

import re
import shutil
import subprocess

import numpy as np
import pytest
import symengine as se
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, Scene, derive, generate_c, generate_fortran, systems

from helpers import STRICT_FFLAGS


MODELS = {
    "pendulum": systems.pendulum,
    "double_pendulum": systems.double_pendulum,
    "oscillator": systems.damped_driven_oscillator,
    "central": systems.central_potential,
    "chain5": lambda: systems.n_link_pendulum(5),
}
OUTPUTS = ["energy", "momenta", "positions"]


@pytest.fixture(scope="module")
def eoms():
    return {name: derive(make()) for name, make in MODELS.items()}


def quadrature_eom():
    """The pendulum with one quadrature state z' = cos(theta) theta'^2 + t (not a real physical
    quantity: it exercises the z rows of rhs and jac)."""
    eom = derive(systems.pendulum("pendz"))
    theta, = (se.Symbol(q.name) for q in eom.model.coords)
    w, = (se.Symbol(v.name) for v in eom.model.speeds)
    eom.quadratures.append(("zeta", se.cos(theta) * w**2 + se.Symbol("t")))
    return eom


def oddities_model():
    """pi, e, sign, rational and negative powers, exp: the printer's special cases."""
    m = lcg.Model("oddities")
    x, = m.coordinates("x")
    k, = m.parameters(k=2.0)
    m.kinetic_energy((1 + x**2 / 10) * m.dot(x) ** 2 / 2)
    m.potential_energy(k * sp.pi * x**2 / 7 + sp.exp(-x**3) / (1 + x**2))
    m.output("s", sp.sign(x) * sp.E + x ** sp.Rational(-1, 2) + x ** sp.Rational(3, 2) + x**-3)
    return m


def strict_compile(fc, code, folder):
    code.write(folder)
    source = f"{code.prefix}.f90"
    for opt in ("-O0", "-O2"):
        proc = subprocess.run([fc, opt, *STRICT_FFLAGS, "-c", source, "-o", f"{code.prefix}.o"], cwd=folder,
                              capture_output=True, text=True)
        assert proc.returncode == 0, f"{opt}:\n{proc.stderr}"
    lines = code.files[source].splitlines()
    assert max(map(len, lines)) <= 132
    return code.files[source]


@pytest.mark.parametrize("name", sorted(MODELS))
def test_fortran_compiles_with_strict_warnings(tmp_path, fc, eoms, name):
    strict_compile(fc, generate_fortran(Scene(eoms[name], outputs=OUTPUTS)), tmp_path)


@pytest.mark.parametrize("variant", ["folded", "bare", "quadrature", "oddities"])
def test_fortran_variants_compile_with_strict_warnings(tmp_path, fc, variant):
    # Unused dummy arguments (no run-time parameters, no time dependence), no jacobian or
    # outputs, quadrature states, and the printer's special cases.
    if variant == "folded":
        scene = Scene(derive(systems.pendulum()), runtime_parameters=[], outputs=["energy"])
    elif variant == "bare":
        scene = Scene(derive(systems.double_pendulum()), jacobian=False)
    elif variant == "quadrature":
        scene = Scene(quadrature_eom(), outputs=["energy"])
    else:
        scene = Scene(derive(oddities_model()), outputs=["s"])
    src = strict_compile(fc, generate_fortran(scene), tmp_path)
    assert ("_jac" in src) == scene.jacobian and ("_outputs" in src) == bool(scene.outputs)


def test_header_is_the_c_backends_header(eoms):
    for eom in eoms.values():
        for kwargs in ({}, {"outputs": OUTPUTS, "runtime_parameters": ["m"] if "m" in
                                 [s.name for s in eom.model.params] else []}):
            c, f = generate_c(Scene(eom, **kwargs)), generate_fortran(Scene(eom, **kwargs))
            assert f.files[f.header_name] == c.files[c.header_name]
            assert sorted(f.files) == sorted([f.header_name, f"{f.prefix}.f90"])


def test_folded_constants_keep_all_digits():
    code = generate_fortran(Scene(derive(systems.double_pendulum()), runtime_parameters=["g"], values={"l2": 0.7}))
    src = code.files["double_pendulum.f90"]
    assert "0.69999999999999996d0" in src
    assert "p(1)" in src and "p(2)" not in src  # g is p[0] in C, p(1) in Fortran
    body = src[src.index("contains"):]
    assert "y(1)" in body and "y[" not in body and "pow(" not in body
    assert 'bind(C, name="double_pendulum_rhs")' in src


def assert_same(a, b, what):
    scale = max(np.max(np.abs(a)), 1e-300)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14 * scale, err_msg=what)


def builds(eom, tag):
    c = lcg.build_code(generate_c(Scene(eom, outputs=OUTPUTS, prefix=f"c_{tag}")))
    f = lcg.build_code(generate_fortran(Scene(eom, outputs=OUTPUTS, prefix=f"f_{tag}")))
    return c, f


INITIAL = {
    "pendulum": dict(q0=[1.2]),
    "double_pendulum": dict(q0=[1.0, 0.5]),
    "oscillator": dict(q0=[1.0], v0=[0.0]),
    "central": dict(q0=[1.0, 0.0], v0=[0.0, 1.1]),
    "chain5": dict(q0=[0.5] * 5),
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_c_and_fortran_agree_to_round_off(fc, eoms, name):
    cm, fm = builds(eoms[name], name)
    rng = np.random.default_rng(7)
    for _ in range(10):
        y = rng.uniform(0.2, 1.2, cm.ny)
        t = rng.uniform(0.0, 3.0)
        assert_same(cm.rhs(t, y), fm.rhs(t, y), "rhs")
        assert_same(cm.jac(t, y), fm.jac(t, y), "jac")
        assert_same(cm.outputs(t, y), fm.outputs(t, y), "outputs")
    # A whole native CVODE run: the Fortran functions behind the same driver.
    rc = cm.simulate([0.0, 5.0], rtol=1e-10, atol=1e-12, **INITIAL[name])
    rf = fm.simulate([0.0, 5.0], rtol=1e-10, atol=1e-12, **INITIAL[name])
    assert rc.stats["steps"] == rf.stats["steps"] and rc.stats["jac_evals"] == rf.stats["jac_evals"]
    for k in range(cm.ny):
        assert_same(rc.y[:, k], rf.y[:, k], f"state {k}")
    for key in rc.outputs:
        assert_same(rc.outputs[key], rf.outputs[key], f"output {key} along the run")


def test_quadrature_states_agree(fc):
    eom = quadrature_eom()
    cm = lcg.build_code(generate_c(Scene(eom, prefix="cz")))
    fm = lcg.build_code(generate_fortran(Scene(eom, prefix="fz")))
    assert fm.ny == 3
    y = np.array([0.7, -0.4, 0.2])
    assert_same(cm.rhs(0.3, y), fm.rhs(0.3, y), "rhs")
    assert_same(cm.jac(0.3, y), fm.jac(0.3, y), "jac")
    assert fm.jac(0.3, y)[2, 0] != 0.0  # d zeta' / d theta


def test_compile_model_fortran_through_the_native_driver(fc):
    sim = lcg.compile_model(systems.damped_driven_oscillator("osc_f"), outputs=["energy"], lang="fortran")
    assert any(name.endswith(".f90") for name in sim.code.files)
    res = sim.simulate(np.linspace(0.0, 40.0, 401), q0=[0.0], v0=[0.0], rtol=1e-10, atol=1e-12)
    # Steady state of m x'' + c x' + k x = F0 cos(w t): amplitude F0 / sqrt((k - m w^2)^2 + (c w)^2).
    m, k, c, F0, w = 1.0, 4.0, 0.4, 1.0, 1.5
    late = res["x"][res.t > 30.0]
    amplitude = F0 / np.hypot(k - m * w**2, c * w)
    assert abs(np.max(np.abs(late)) - amplitude) < 2e-3 * amplitude
    with pytest.raises(ModelError, match="cobol"):
        lcg.compile_model(systems.pendulum(), lang="cobol")


def test_error_codes_match_the_c_backend(fc):
    # Singular mass matrix (M = x^2 at x = 0) -> 1, non-finite force (V = 1/x at x = 0) -> 2,
    # indefinite M -> LU fallback.
    m = lcg.Model("singular")
    x, = m.coordinates("x")
    m.kinetic_energy(x**2 * m.dot(x) ** 2 / 2)
    m.potential_energy(x**2 / 2)
    sing = derive(m)
    m = lcg.Model("blowup")
    x, = m.coordinates("x")
    m.kinetic_energy(m.dot(x) ** 2 / 2)
    m.potential_energy(1 / x)
    blow = derive(m)
    m = lcg.Model("indef")
    x, y = m.coordinates("x y")
    m.kinetic_energy(-m.dot(x) ** 2 / 2 + m.dot(y) ** 2 / 2 + m.dot(x) * m.dot(y) / 4)
    m.potential_energy(x**2 / 2 + y**2 / 2 + x * y / 3)
    indef = derive(m)
    for gen in (generate_c, generate_fortran):
        tag = "c" if gen is generate_c else "f"
        cm = lcg.build_code(gen(Scene(sing, prefix=f"sing_{tag}")), native=False)
        with pytest.raises(lcg.SingularMassMatrixError):
            cm.rhs(0.0, [0.0, 1.0])
        with pytest.raises(lcg.SingularMassMatrixError):
            cm.jac(0.0, [0.0, 1.0])
        cm = lcg.build_code(gen(Scene(blow, prefix=f"blow_{tag}")), native=False)
        with pytest.raises(lcg.SolverError, match="not finite"):
            cm.rhs(0.0, [0.0, 1.0])
        cm = lcg.build_code(gen(Scene(indef, prefix=f"indef_{tag}")), native=False)
        state = np.array([0.3, -0.5, 0.1, 0.2])
        M = np.array(indef.M, dtype=float)
        F = np.array(indef.F.subs(dict(zip(indef.q + indef.qd, state))), dtype=float).ravel()
        np.testing.assert_allclose(cm.rhs(0.0, state)[2:], np.linalg.solve(M, F), rtol=1e-13)


def test_prefix_must_be_a_fortran_name():
    eom = derive(systems.pendulum())
    with pytest.raises(ModelError, match="Fortran"):
        generate_fortran(Scene(eom, prefix="_pendulum"))
    with pytest.raises(ModelError, match="Fortran"):
        generate_fortran(Scene(eom, prefix="p" * 46))
    generate_fortran(Scene(eom, prefix="p" * 45))


FORTRAN_CALLER = """\
program caller
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  use double_pendulum_mod
  implicit none
  real(c_double) :: y(double_pendulum_ny), ydot(double_pendulum_ny), p(double_pendulum_np)
  real(c_double) :: jac(double_pendulum_ny, double_pendulum_ny), out(double_pendulum_nout)
  integer(c_int) :: rc
  y = [0.4_c_double, -1.1_c_double, 0.3_c_double, 0.8_c_double]
  p = [1.0_c_double, 1.0_c_double, 1.0_c_double, 1.0_c_double, 9.81_c_double]
  rc = double_pendulum_rhs(0.5_c_double, y, p, ydot)
  if (rc /= double_pendulum_ok) error stop 1
  rc = double_pendulum_jac(0.5_c_double, y, ydot, p, jac)
  if (rc /= double_pendulum_ok) error stop 2
  rc = double_pendulum_outputs(0.5_c_double, y, p, out)
  if (rc /= double_pendulum_ok) error stop 3
  write (*, '(es25.17)') ydot, jac, out
end program caller
"""


def test_fortran_programs_use_the_module(tmp_path, fc):
    eom = derive(systems.double_pendulum())
    code = generate_fortran(Scene(eom, outputs=["energy"]))
    assert code.param_names == ["l1", "l2", "m1", "m2", "g"]
    code.write(tmp_path)
    (tmp_path / "caller.f90").write_text(FORTRAN_CALLER)
    proc = subprocess.run([fc, *STRICT_FFLAGS, "double_pendulum.f90", "caller.f90", "-o", "caller"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./caller"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    values = np.array([float(v) for v in run.stdout.split()])
    cm = lcg.build_code(generate_c(Scene(eom, outputs=["energy"], prefix="dp_caller")))
    y = [0.4, -1.1, 0.3, 0.8]
    expected = np.concatenate([cm.rhs(0.5, y), cm.jac(0.5, y).ravel(order="F"), cm.outputs(0.5, y)])
    np.testing.assert_allclose(values, expected, rtol=1e-15, atol=1e-15)


def test_long_sums_are_split_in_c_order(tmp_path, fc, monkeypatch):
    # Statements too long for Fortran's 255 continuation lines become running partial sums
    # (target = a + b; target = target + c ...): the same additions in the same order.
    import lagcodegen.codegen.fortran_printer as fortran_printer
    monkeypatch.setattr(fortran_printer, "MAX_CONTINUATIONS", 1)
    eom = derive(systems.n_link_pendulum(3))
    code = generate_fortran(Scene(eom, outputs=["energy"], prefix="split3"))
    src = strict_compile(fc, code, tmp_path)
    assert re.search(r"\n *(F\(1\)) = \1 [-+] ", src) and re.search(r"\n *(G\(1, 1\)) = \1 [-+] ", src)
    cm = lcg.build_code(generate_c(Scene(eom, outputs=["energy"], prefix="split3c")))
    fm = lcg.build_code(code)
    y = np.array([0.3, -0.2, 0.9, 0.1, 0.4, -0.7])
    assert_same(cm.rhs(0.0, y), fm.rhs(0.0, y), "rhs")
    assert_same(cm.jac(0.0, y), fm.jac(0.0, y), "jac")
