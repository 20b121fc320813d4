"""Generated Fortran for constrained systems: strict gfortran, the same numbers as the C
functions (index-1 solve, residuals, projection, outputs, roots, GGL residual and Jacobian),
the same native CVODE/IDA runs, the same error codes, and C callers that cannot tell the two apart."""

import platform
import subprocess

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen import ModelError, SingularMassMatrixError, SolverError
from lagcodegen.theory.constraints import ConstrainedSystem
from lagcodegen.api import compile_constrained
from lagcodegen.build import dae_table_source, table_source
from lagcodegen.codegen.constrained import generate_constrained_c, generate_constrained_fortran
from lagcodegen.model.events import Event

from helpers import atwood, cartesian_pendulum, knife_edge, mixed_system, pendulum_q0
from helpers import STRICT_FFLAGS

OUTPUTS = ["energy", "lambda", "residuals", "constraint_forces"]
#: On x86-64 neither gcc (-std=c99) nor gfortran (-ffp-contract=off) fuses multiply-adds, and the
#: Fortran evaluates the C operations in the C order: the results are the same doubles.
BIT_IDENTICAL = platform.machine() in ("x86_64", "AMD64")


def free_ball():
    """No equality constraint at all (J = 0), one inequality: the code paths with empty arrays."""
    m = lcg.Model("free")
    x, y = m.coordinates("x y")
    m.particle("b", 1.0, (x, y))
    m.gravity(9.81)
    return ConstrainedSystem(m, inequalities=[y])


def lam_event(cs):
    return [Event("lam", cs.multipliers[0], 0, False)] if cs.J else []


# ---------------------------------------------------------------------- strict compilation
VARIANTS = {
    "pendulum": lambda: (cartesian_pendulum("fpend"), dict(ggl=True, outputs=OUTPUTS)),
    "knife": lambda: (knife_edge("fknife"), dict(ggl=True, outputs=OUTPUTS)),  # J = 1, JH = 0
    "mixed": lambda: (mixed_system(), dict(ggl=True, outputs=OUTPUTS)),  # J = 2, JH = 1, f(q, t)
    "free": lambda: (free_ball(), dict(ggl=True, outputs=["energy", "inequalities"])),  # J = 0
    "folded": lambda: (atwood("fatwood"), dict(ggl=True, ggl_jacobian=False, runtime_parameters=[],
                                                outputs=["energy"])),
    "bare": lambda: (cartesian_pendulum("fbare"), dict(outputs=[])),  # index-1 only, no outputs
}


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_constrained_fortran_compiles_with_strict_warnings(tmp_path, fc, name):  # noqa: F811
    cs, options = VARIANTS[name]()
    code, info = generate_constrained_fortran(cs, events=lam_event(cs), **options)
    c_code, _ = generate_constrained_c(cs, events=lam_event(cs), **options)
    pre = info.prefix
    # The headers and the function tables (through which the runtime's drivers call the model) are
    # the C backend's, byte for byte.
    for fname in (f"{pre}_dae.h", f"{pre}.h"):
        assert code.files[fname] == c_code.files[fname], fname
    assert code.dae == c_code.dae
    assert dae_table_source(code) == dae_table_source(c_code) and table_source(code) == table_source(c_code)
    assert f"{pre}_dae.c" not in code.files and f"{pre}.c" not in code.files
    code.write(tmp_path)
    for opt in ("-O0", "-O2"):
        for src in (f"{pre}.f90", f"{pre}_dae.f90"):
            proc = subprocess.run([fc, opt, *STRICT_FFLAGS, "-c", src], cwd=tmp_path, capture_output=True, text=True)
            assert proc.returncode == 0, f"{src} {opt}:\n{proc.stderr}"
    src = code.files[f"{pre}_dae.f90"]
    assert max(map(len, src.splitlines())) <= 132
    body = src[src.index("contains"):]
    assert "y[" not in body and "lam[" not in body and "pow(" not in body
    for fn in ("kkt", "crhs", "residuals", "project", "coutputs", "natural_rate"):
        assert f'bind(C, name="{pre}_{fn}")' in src
    assert (f'name="{pre}_ggl_res"' in src) == options.get("ggl", False)
    assert (f'name="{pre}_ggl_jac"' in src) == (options.get("ggl", False) and options.get("ggl_jacobian", True))
    assert (f'name="{pre}_roots"' in src) == bool(info.events)


# ---------------------------------------------------------------------- C and Fortran agree
SYSTEMS = {
    "pendulum": (cartesian_pendulum, dict(q0=pendulum_q0(), v0=[0.0, 0.0]), 5.0),
    "atwood": (atwood, dict(q0=[0.5, 1.5], v0=[0.0, 0.0]), 1.0),
    "knife": (knife_edge, dict(q0=[0.0, 0.0, 0.0], v0=[0.0, 0.0, 1.5]), 10.0),
}
PAIRS = [(name, form) for name in SYSTEMS for form in ("index1", "ggl")]


@pytest.fixture(scope="module")
def pairs():
    built = {}
    for name, form in PAIRS:
        make = SYSTEMS[name][0]
        for lang in ("c", "fortran"):
            cs = make(name=f"{name[:4]}_{form}_{lang[0]}")
            built[name, form, lang] = compile_constrained(cs, form, outputs=OUTPUTS, events=lam_event(cs), lang=lang)
    return built


def same(a, b, what):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, what
    scale = max(float(np.max(np.abs(a), initial=0.0)), 1e-300)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14 * scale, err_msg=what)
    if BIT_IDENTICAL:
        assert np.array_equal(a, b), f"{what}: not bit-identical (max diff {np.max(np.abs(a - b)):.3g})"


def crhs(sim, t, y, alpha, beta):
    ydot, p = np.empty(y.size), sim.parameter_vector()
    assert sim.c_crhs(t, sim._ptr(y), sim._ptr(p), alpha, beta, sim._ptr(ydot)) == 0
    return ydot


@pytest.mark.parametrize("name,form", PAIRS)
def test_c_and_fortran_constrained_functions_agree(fc, pairs, name, form):  # noqa: F811
    c, f = pairs[name, form, "c"], pairs[name, form, "fortran"]
    assert f.info.lang == "fortran" and any(k.endswith("_dae.f90") for k in f.compiled.code.files)
    rng = np.random.default_rng(11)
    n = c.n
    for _ in range(10):
        y = rng.uniform(-1.0, 1.0, 2 * n)
        t = rng.uniform(0.0, 2.0)
        alpha, beta = rng.uniform(0.0, 5.0, 2)
        for k, (a, b) in enumerate(zip(c.kkt(t, y, None, alpha, beta), f.kkt(t, y, None, alpha, beta))):
            same(a, b, ("acc", "lam")[k])
        for k, (a, b) in enumerate(zip(c.residuals(t, y), f.residuals(t, y))):
            same(a, b, ("g", "s")[k])
        same(crhs(c, t, y, alpha, beta), crhs(f, t, y, alpha, beta), "crhs")
        same(c.natural_rate(t, y), f.natural_rate(t, y), "natural_rate")
        same(c.project(t, y), f.project(t, y), "project")
        same(c.outputs(t, y), f.outputs(t, y), "outputs (lam from the augmented system)")
        lam = rng.normal(size=c.info.J)
        same(c.outputs(t, y, lam=lam), f.outputs(t, y, lam=lam), "outputs (lam given)")
        same(c.roots(t, y), f.roots(t, y), "roots")
        if form == "ggl":
            ng = c.info.ng
            yy, yp, cj = rng.normal(size=ng), rng.normal(size=ng), rng.uniform(1.0, 100.0)
            same(c.ggl_residual(t, yy, yp), f.ggl_residual(t, yy, yp), "GGL residual")
            same(c.ggl_jacobian(t, cj, yy, yp), f.ggl_jacobian(t, cj, yy, yp), "GGL Jacobian")

    # A whole native run: the Fortran functions behind the same C drivers (index 1 with CVODE's
    # projection, which also projects the error estimate; GGL on IDA with the generated Jacobian).
    _, ic, t_end = SYSTEMS[name]
    opts = dict(projection=True) if form == "index1" else {}
    t = np.linspace(0.0, t_end, 51)
    rc_, rf_ = (sim.simulate(t, rtol=1e-10, atol=1e-12, **ic, **opts) for sim in (c, f))
    for key in ("steps", "rhs_evals", "jac_evals"):
        assert rc_.stats[key] == rf_.stats[key], key
    same(rc_.y, rf_.y, "states along the run")
    for key in rc_.outputs:
        same(rc_.outputs[key], rf_.outputs[key], f"output {key} along the run")
    assert [(e.name, e.t) for e in rc_.events] == [(e.name, e.t) for e in rf_.events]
    assert rc_.stats.get("projections", 0) == rf_.stats.get("projections", 0)
    if form == "index1":
        assert rf_.stats["projections"] > 0


def test_fortran_error_codes_match_the_c_functions(fc):  # noqa: F811
    # Singular augmented matrix: two constraints tangent at (l, 0); projection that cannot
    # converge (x^2 + y^2 + l^2 = 0 has no real solution); non-finite input.
    base = cartesian_pendulum("ferr").model
    x, y = base.coords
    l = sp.Symbol("l")
    for lang in ("c", "fortran"):
        tangent = compile_constrained(ConstrainedSystem(base, holonomic=[x ** 2 + y ** 2 - l ** 2, x - l]), "index1",
                                      prefix=f"tangent_{lang[0]}", lang=lang)
        with pytest.raises(SingularMassMatrixError, match="singular"):
            tangent.kkt(0.0, [1.0, 0.0, 0.0, 0.0])
        with pytest.raises(ModelError, match="A A\\^T is singular"):
            tangent.project(0.0, [1.0, 0.0, 0.0, 0.0])
        noreal = compile_constrained(ConstrainedSystem(base, holonomic=[x ** 2 + y ** 2 + l ** 2]), "index1",
                                     prefix=f"noreal_{lang[0]}", lang=lang)
        with pytest.raises(ModelError, match="did not converge in 7 steps"):
            noreal.project(0.0, [0.3, 0.4, 0.0, 0.0], maxit=7)
        with pytest.raises(SolverError, match="not finite"):
            noreal.residuals(0.0, [np.nan, 0.4, 0.0, 0.0])
        with pytest.raises(SolverError, match="not finite"):
            noreal.kkt(0.0, [0.3, 0.4, np.inf, 0.0])  # gamma = -inf


def test_minimal_coordinates_in_fortran_equal_c():
    cs = cartesian_pendulum("fmin")
    t = np.linspace(0, 3, 31)
    runs = [compile_constrained(cs, "minimal", lang=lang).simulate(t, q0=[0.6, -0.8], rtol=1e-10, atol=1e-12)
            for lang in ("c", "fortran")]
    np.testing.assert_allclose(runs[1].y, runs[0].y, rtol=1e-12, atol=1e-14)
    assert runs[0].stats["steps"] == runs[1].stats["steps"]


def skating_body():
    """A body on a free joint (quaternion) whose body point (0.3, 0, 0) has its world x velocity
    held at zero: one row in q' given as nonholonomic and no holonomic one (JH = 0)."""
    m = lcg.Model("fskate")
    m.link("b", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.1, 0.2, 0.3, 0, 0, 0))
    m.gravity(9.81)
    x = m.point_on("b", (0.3, 0, 0), "tip").position[0]
    return ConstrainedSystem(m, nonholonomic=[[sp.diff(x, q) for q in m.coords]], check_integrability=False)


def pinned_quaternion_body():
    """A body on a free joint whose body point (0.1, 0.2, 0.5) is held at the origin (JH = 3)."""
    m = lcg.Model("fpinned")
    m.link("body", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.1, 0.2, 0.3, 0, 0, 0))
    m.gravity(9.81)
    return ConstrainedSystem(m, holonomic=list(m.point_on("body", (0.1, 0.2, 0.5), "pivot").position))


@pytest.mark.parametrize("make", [pinned_quaternion_body, skating_body])
def test_generalized_speeds_in_fortran_compile_strictly_and_run_as_c(tmp_path, fc, make):  # noqa: F811
    """Constrained systems with generalized speeds (q' = k(q, v), the quaternion renormalized in
    the projection) in Fortran: strict gfortran, the C headers byte for byte, and the same run as
    the C functions' (index 1 on CVODE, an event on a multiplier, the outputs), and the same
    projection from a state off the constraints."""
    cs = make()
    events = lam_event(cs) if cs.n_holonomic else []
    code, info = generate_constrained_fortran(cs, events=events, outputs=OUTPUTS)
    c_code, _ = generate_constrained_c(cs, events=events, outputs=OUTPUTS)
    pre = info.prefix
    assert code.files[f"{pre}_dae.h"] == c_code.files[f"{pre}_dae.h"] and code.dae == c_code.dae
    code.write(tmp_path)
    for opt in ("-O0", "-O2"):
        proc = subprocess.run([fc, opt, *STRICT_FFLAGS, "-c", f"{pre}.f90", f"{pre}_dae.f90"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, f"{opt}:\n{proc.stderr}"
    assert max(map(len, code.files[f"{pre}_dae.f90"].splitlines())) <= 132
    sims = [compile_constrained(cs, lang=lang, outputs=OUTPUTS, events=events) for lang in ("c", "fortran")]
    assert sims[1].ny == sims[0].ny == 13
    w = np.array([0.7, -1.1, 2.3])
    if cs.n_holonomic:
        q0, v0 = np.array([-0.1, -0.2, -0.5, 0, 0, 0, 1]), np.concatenate([-np.cross(w, [0.1, 0.2, 0.5]), w])
    else:
        q0, v0 = np.array([0, 0, 1.0, 0, 0, 0, 1]), np.concatenate([[0, 0.4, 2.0], w])
        v0[0] = -np.cross(w, [0.3, 0, 0])[0]  # the tip's x velocity zero (R = I)
    t = np.linspace(0.0, 2.0, 21)
    runs = [sim.simulate(t, q0, v0, rtol=1e-10, atol=1e-12) for sim in sims]
    assert np.ptp(runs[0].y[:, 3:7], axis=0).max() > 0.1  # it turns
    same(runs[0].y, runs[1].y, "states along the run")
    for key in runs[0].outputs:
        same(runs[0].outputs[key], runs[1].outputs[key], f"output {key} along the run")
    assert runs[0].stats["steps"] == runs[1].stats["steps"]
    assert [(e.name, e.t) for e in runs[0].events] == [(e.name, e.t) for e in runs[1].events]
    rng = np.random.default_rng(3)
    for _ in range(5):  # the functions at states off the constraints
        y = np.concatenate([q0 + rng.normal(scale=0.1, size=7), rng.normal(size=6)])
        same(crhs(sims[0], 0.3, y, 1.0, 2.0), crhs(sims[1], 0.3, y, 1.0, 2.0), "crhs")
        same(sims[0].natural_rate(0.3, y), sims[1].natural_rate(0.3, y), "natural_rate")
        same(sims[0].outputs(0.3, y), sims[1].outputs(0.3, y), "outputs")
    g, s = sims[1].residuals(t[-1], runs[1].y[-1])
    assert np.abs(g).max(initial=0.0) < 1e-9 and np.abs(s).max() < 1e-9
    y = np.concatenate([q0 + 1e-3, v0 + 0.1])
    yp = [sim.project(0.0, y) for sim in sims]
    np.testing.assert_allclose(yp[1], yp[0], rtol=1e-14, atol=1e-15)
    assert abs(np.linalg.norm(yp[1][3:7]) - 1) < 1e-14


def test_language_option_errors():
    cs = cartesian_pendulum("flang")
    with pytest.raises(ModelError, match="cobol"):
        compile_constrained(cs, "index1", lang="cobol")
    with pytest.raises(ModelError, match="Fortran"):
        generate_constrained_fortran(cs, prefix="_bad")
    with pytest.raises(ModelError, match="at most 44 characters"):
        generate_constrained_fortran(cs, prefix="p" * 45)


# ---------------------------------------------------------------------- C callers
CALLER = r"""
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "P_dae.h"

#define NJD (U_DAE_NJ > 0 ? U_DAE_NJ : 1)
#define NJHD (U_DAE_NJH > 0 ? U_DAE_NJH : 1)

static void show(const char *what, int rc, const double *x, int n)
{
    int i;
    printf("%s rc=%d", what, rc);
    for (i = 0; i < n; ++i)
        printf(" %.17g", x[i]);
    printf("\n");
}

int main(void)
{
    double p[U_DAE_NP + 1] = PARAMS, y[U_DAE_NY], yn[U_DAE_NY], err[U_DAE_NY], acc[U_DAE_NQ], lam[NJD];
    double yd[U_DAE_NY], g[NJHD], s[NJD], out[U_DAE_NOUT], gout[U_DAE_NROOT];
    double yy[U_DAE_NG], yp[U_DAE_NG], rr[U_DAE_NG], jac[U_DAE_NG * U_DAE_NG];
    int i;

    for (i = 0; i < U_DAE_NY; ++i) {
        y[i] = 0.3 + 0.17 * i - 0.05 * i * i;
        err[i] = 1e-3 * (i + 1);
    }
    show("kkt", P_kkt(0.1, y, p, 1.0, 2.0, acc, lam), acc, U_DAE_NQ);
    show("lam", 0, lam, U_DAE_NJ);
    show("kkt_null", P_kkt(0.1, y, p, 0.0, 0.0, acc, NULL), acc, U_DAE_NQ);
    show("crhs", P_crhs(0.1, y, p, 0.5, 0.25, yd), yd, U_DAE_NY);
    show("residuals_g", P_residuals(0.1, y, p, g, s), g, U_DAE_NJH);
    show("residuals_s", 0, s, U_DAE_NJ);
    show("project", P_project(0.1, y, p, 1e-14, 20, yn, err), yn, U_DAE_NY);
    show("project_err", 0, err, U_DAE_NY);
    memcpy(yd, y, sizeof y);
    show("project_in_place", P_project(0.1, yd, p, 1e-14, 20, yd, NULL), yd, U_DAE_NY);
    show("project_maxit", P_project(0.1, y, p, 0.0, 1, yd, NULL), yd, 0);
    show("coutputs_null", P_coutputs(0.1, yn, NULL, p, out), out, U_DAE_NOUT);
    show("coutputs_lam", P_coutputs(0.1, yn, lam, p, out), out, U_DAE_NOUT);
    show("roots_null", P_roots(0.1, yn, NULL, p, gout), gout, U_DAE_NROOT);
    show("roots_lam", P_roots(0.1, yn, lam, p, gout), gout, U_DAE_NROOT);
    for (i = 0; i < U_DAE_NG; ++i) {
        yy[i] = 0.2 - 0.11 * i;
        yp[i] = 0.05 * i;
    }
    show("ggl_res", P_ggl_res(0.1, yy, yp, p, rr), rr, U_DAE_NG);
    show("ggl_jac", P_ggl_jac(0.1, 10.0, yy, yp, p, jac), jac, U_DAE_NG * U_DAE_NG);
    y[U_DAE_NQ] = INFINITY; /* a velocity: gamma is not finite */
    show("kkt_inf", P_kkt(0.1, y, p, 0.0, 0.0, acc, lam), acc, 0);
    return 0;
}
"""


@pytest.mark.parametrize("name", ["pendulum", "mixed"])
def test_c_callers_see_the_same_functions_under_sanitizers(tmp_path, cc, fc, name):  # noqa: F811
    """One C program (NULL multipliers and error estimate, in-place projection, failed
    projection, NaN input) linked with the C and with the Fortran functions, under
    AddressSanitizer and UBSan: the same printed digits."""
    cs = cartesian_pendulum("callp") if name == "pendulum" else mixed_system()
    events = lam_event(cs)
    outputs = {}
    san = ["-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    for lang in ("c", "fortran"):
        folder = tmp_path / lang
        code, info = generate_constrained_c(cs, ggl=True, events=events, outputs=OUTPUTS, lang=lang)
        code.write(folder)
        pre = info.prefix
        params = "{" + ", ".join(repr(float(v)) for v in code.param_defaults) + (", 0.0}" if code.param_defaults
                                                                                  else "0.0}")
        main = CALLER.replace("P_", f"{pre}_").replace("U_", f"{pre.upper()}_").replace("PARAMS", params)
        (folder / "main.c").write_text(main)
        objects = ["main.c"]
        if lang == "fortran":
            proc = subprocess.run([fc, *san, "-ffp-contract=off", *STRICT_FFLAGS, "-c", f"{pre}_dae.f90"], cwd=folder,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr
            objects += [f"{pre}_dae.o", "-lgfortran"]
        else:
            objects.insert(0, f"{pre}_dae.c")
        proc = subprocess.run([cc, *san, "-std=c99", *objects, "-o", "main", "-lm"], cwd=folder, capture_output=True,
                              text=True)
        assert proc.returncode == 0, proc.stderr
        run = subprocess.run(["./main"], cwd=folder, capture_output=True, text=True,
                             env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
        assert run.returncode == 0, run.stdout + run.stderr
        assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr
        outputs[lang] = run.stdout
    lines = dict(line.split(" ", 1) for line in outputs["c"].splitlines())
    assert lines["kkt"].startswith("rc=0") and lines["project"].startswith("rc=0")
    assert lines["project_maxit"].startswith("rc=3") and lines["kkt_inf"].startswith("rc=2")
    assert lines["project"] == lines["project_in_place"]
    if BIT_IDENTICAL:
        assert outputs["fortran"] == outputs["c"]
    else:
        for a, b in zip(outputs["c"].splitlines(), outputs["fortran"].splitlines()):
            va, vb = a.split()[2:], b.split()[2:]
            np.testing.assert_allclose(np.array(vb, float), np.array(va, float), rtol=1e-12, atol=1e-14)
