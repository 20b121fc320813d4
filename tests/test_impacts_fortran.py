"""Contacts of constrained systems whose model code is Fortran (``lang="fortran"``): the contact
functions ``<prefix>_impact.f90`` with their C tables ``<prefix>_impact_table.c`` on the same
native impact drivers as the C code. Checked against the closed forms the C tests use (bouncing
ball, Newton's cradle, a block on an incline with Coulomb friction, planar and 3-D, a sphere on
generalized speeds) and against the same systems with C model code: the same doubles where
neither compiler fuses multiply-adds (x86-64: gcc -std=c99, gfortran -ffp-contract=off, the
Fortran evaluating the C operations in the C order), else to 1e-12 relative; strict gfortran; C
callers under the sanitizers."""

from __future__ import annotations

import math
import platform
import subprocess

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.api import compile_constrained
from lagcodegen.codegen.constrained import generate_constrained
from lagcodegen.codes import c_header
from lagcodegen.runtime import sources as runtime_files
from lagcodegen.simulation.constrained_impacts import ImpactRunner

from helpers import STRICT_FFLAGS
from test_friction import _incline
from test_friction_speeds import MU, RADIUS, _incline_3d, _sphere_system, _start
from test_impacts import _ball, newtons_cradle, housner_block

G = 9.81
TIGHT = {"rtol": 1e-12, "atol": 1e-14}
#: As tests/codegen/test_fortran_constrained.py: on x86-64 neither compiler fuses multiply-adds and
#: the Fortran evaluates the C operations in the C order: the results are the same doubles.
BIT_IDENTICAL = platform.machine() in ("x86_64", "AMD64")


def same(a, b, what):
    """``b`` equals ``a``: bit for bit where BIT_IDENTICAL, else to 1e-12 relative."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, what
    scale = max(float(np.max(np.abs(a), initial=0.0)), 1e-300)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-14 * scale, err_msg=what)
    if BIT_IDENTICAL:
        assert np.array_equal(a, b), f"{what}: not bit-identical (max diff {np.max(np.abs(a - b)):.3g})"


def same_runs(rc, rf):
    """The Fortran run ``rf`` is the C run ``rc``: states, outputs, steps and every contact record."""
    assert rc.stats["steps"] == rf.stats["steps"]
    same(rc.y, rf.y, "states along the run")
    for key in rc.outputs:
        same(rc.outputs[key], rf.outputs[key], f"output {key}")
    assert [(r.kind, r.contact) for r in rc.impacts] == [(r.kind, r.contact) for r in rf.impacts]
    same([r.t for r in rc.impacts], [r.t for r in rf.impacts], "contact record times")
    assert rc.impacts.final_modes == rf.impacts.final_modes
    assert rc.impacts.friction_modes == rf.impacts.friction_modes


# ---------------------------------------------------------------------- the generated files
def _wall_pendulum():
    """A Cartesian pendulum (J = JH = 1) whose bob meets a wall x <= 0.3 (restitution 0.7)."""
    import sympy as sp
    m = lcg.Model("fwall")
    x, y = m.coordinates("x y")
    m.parameters(l=1.0, g=G, m=1.0)
    m.particle("bob", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    return lcg.ConstrainedSystem(m, holonomic=[x**2 + y**2 - sp.Symbol("l") ** 2],
                                 inequalities=[lcg.Inequality(0.3 - x, restitution=0.7)])


def _rough_box(name: str, friction):
    """A box on a free joint (quaternion: generalized speeds) with one corner on the floor, rough
    in x and y (3-D Coulomb friction, or no slip with ``friction`` None)."""
    m = lcg.Model(name)
    m.link("box", joint=lcg.Joint.free("root"), mass=1.0, inertia=(0.1, 0.2, 0.3, 0, 0, 0))
    m.gravity(G)
    return lcg.ConstrainedSystem(m, inequalities=[
        lcg.ground_contact(m, "box", (0.1, 0.05, -0.1), restitution=0.3, tangent="xy", friction=friction)])


VARIANTS = {  # (system, ggl): J = 0 and 1, no-slip rows, planar and 3-D friction, generalized speeds
    "wall": (_wall_pendulum, False),
    "wall_ggl": (_wall_pendulum, True),
    "housner_ggl": (lambda: housner_block("fhousner", 0.2, 0.6), True),
    "box3": (lambda: _rough_box("fbox3", 0.5), False),
    "box_noslip_ggl": (lambda: _rough_box("fboxns", None), True),
}


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_fortran_contact_code_compiles_strictly_with_the_c_tables(tmp_path, fc, cc, name):
    make, ggl = VARIANTS[name]
    system = make()
    code, info = generate_constrained(system, ggl=ggl, lang="fortran")
    c_code, _ = generate_constrained(system, ggl=ggl)
    pre = info.prefix
    assert info.contacts == tuple(system.contacts)
    assert f"{pre}_impact.c" not in code.files and code.files["lcg_imp_model.h"] == c_code.files["lcg_imp_model.h"]
    source, table, c_source = code.files[f"{pre}_impact.f90"], code.files[f"{pre}_impact_table.c"], \
        c_code.files[f"{pre}_impact.c"]
    # the tables are the C file's text (the same macros), the friction table with the bound eval
    start = c_source.index(f"extern const lcg_imp_model {pre}_imp_model;")
    end = c_source.index("static int imp_eval(") if "static int imp_eval(" in c_source else len(c_source)
    assert c_source[start:end].split("\n\n/* ")[0] in table
    numbers = system.has_friction or ggl
    assert (f"{pre}_imp_eval, &{pre}_imp_model" in table) == numbers
    assert (f'bind(C, name="{pre}_imp_eval")' in source) == numbers
    for fn in ("gaps", "crhs", "impact"):
        assert f'bind(C, name="{pre}_imp_{fn}")' in source
    assert max(map(len, source.splitlines())) <= 132
    code.write(tmp_path)
    for opt in ("-O0", "-O2"):
        proc = subprocess.run([fc, opt, *STRICT_FFLAGS, "-c", f"{pre}.f90", f"{pre}_dae.f90", f"{pre}_impact.f90"],
                              cwd=tmp_path, capture_output=True, text=True)
        assert proc.returncode == 0, f"{opt}:\n{proc.stderr}"
    for fname, text in {**runtime_files(("lcg_dae_model.h", "lcg_model.h")), "lcg_codes.h": c_header()}.items():
        (tmp_path / fname).write_text(text)
    proc = subprocess.run([cc, "-Wall", "-Wextra", "-Werror", "-std=c99", "-pedantic", "-c", f"{pre}_impact_table.c",
                           "-o", "/dev/null"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


# ---------------------------------------------------------------------- the functions agree
@pytest.mark.parametrize("name", ["wall", "housner_ggl", "box3"])
def test_fortran_contact_functions_equal_the_c_ones(name):
    """gaps, the index-1 right-hand side for every active set (lam NULL and not), the impact, and
    the friction table's numbers at random states, through the tables the drivers read; the
    Housner block resting flat on both no-slip corners (dependent rows: the regularized solve)."""
    make, ggl = VARIANTS[name]
    system = make()
    sims = [compile_constrained(system, "ggl" if ggl else "index1", lang=lang, outputs=["energy"])
            for lang in ("c", "fortran")]
    runners = [ImpactRunner(sim) for sim in sims]
    ffi = runners[0].ffi
    nk, nrow = runners[0].table.nk, runners[0].table.nrow
    nq, ny = runners[0].table.nq, sims[0].ny
    nv = ny - nq
    assert (runners[1].table.nk, runners[1].table.nrow, runners[1].table.nq) == (nk, nrow, nq)
    rng = np.random.default_rng(7)
    states = [rng.uniform(-1.0, 1.0, ny) for _ in range(6)]
    if name == "housner_ggl":  # flat on the floor, at rest: both corners' rows held, dependent
        states.append(np.array([0.0, 0.6, 0.0, 0.0, 0.0, 0.0]))
    p = [np.ascontiguousarray(sim.parameter_vector(), dtype=float) for sim in sims]

    def buf(a):
        return ffi.from_buffer("double[]", a)

    for y in states:
        y = np.ascontiguousarray(y)
        g = [r.gaps(0.3, y, pp) for r, pp in zip(runners, p)]
        same(g[0][0], g[1][0], "gaps")
        same(g[0][1], g[1][1], "normal velocities")
        for mask in range(1 << nk):
            active = ffi.new("int[]", [(mask >> k) & 1 for k in range(nk)])
            e = np.full(nk, 0.5)
            out = []
            for r, pp in zip(runners, p):
                ydot, lam, ynew, imp = np.zeros(ny), np.zeros(nrow), np.zeros(ny), np.zeros(nrow)
                rc1 = r.table.crhs(0.3, buf(y), buf(pp), 1.5, 2.5, active, buf(ydot), buf(lam))
                rc2 = r.table.crhs(0.3, buf(y), buf(pp), 1.5, 2.5, active, buf(np.zeros(ny)), ffi.NULL)
                rc3 = r.table.impact(0.3, buf(y), buf(pp), active, buf(e), buf(ynew), buf(imp))
                out.append((rc1, rc2, rc3, ydot, lam, ynew, imp))
            assert out[0][:3] == out[1][:3] == (0, 0, 0), (mask, out[0][:3], out[1][:3])
            for k, what in enumerate(("crhs", "multipliers", "impact", "impulses")):
                same(out[0][3 + k], out[1][3 + k], f"{what}, active {mask:b}")
        if runners[0].numbers != ffi.NULL:
            got = []
            for r, pp in zip(runners, p):
                arrays = [np.zeros(nv * nv), np.zeros(nv), np.zeros(nrow * nv), np.zeros(nrow), np.zeros(nrow),
                          np.zeros(nrow), np.zeros(nq)]
                assert r.numbers.eval(0.3, buf(y), buf(pp), *map(buf, arrays)) == 0
                got.append(arrays)
            for a, b, what in zip(*got, ("M", "F", "R", "s", "h", "gamma", "q'")):
                same(a, b, f"friction table {what}")


# ---------------------------------------------------------------------- runs against closed forms
@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_fortran_bouncing_ball_impact_times_apex_heights_and_resting_force(formulation):
    """The bounds of test_impacts' bouncing ball: impact k at t1 + 2 t1 e (1 - e^k) / (1 - e), the
    rebound speeds and apex heights h0 e^(2k) to 1e-9, the ball held at rest by lambda = m g; the
    run the C code's."""
    e, h0 = 0.8, 1.0
    t1 = math.sqrt(2 * h0 / G)
    runs = {}
    for lang in ("c", "fortran"):
        ball = _ball(e, formulation, lang=lang)
        runs[lang] = ball.simulate(np.linspace(0, 6, 6001), q0=[h0], v0=[0.0], contacts=lcg.ContactOptions(
            contact_speed=1e-6), **TIGHT)
    res = runs["fortran"]
    bounces = res.impacts.select("bounce")
    assert len(bounces) >= 20
    k = np.arange(20)
    t_found = np.array([r.t for r in bounces[:20]])
    assert np.max(np.abs(t_found / (t1 + 2 * t1 * e * (1 - e**k) / (1 - e)) - 1)) < 1e-9
    w_after = np.array([r.w_after for r in bounces[:20]])
    assert np.max(np.abs(w_after / (e ** (k + 1) * math.sqrt(2 * G * h0)) - 1)) < 1e-9
    assert np.max(np.abs(w_after**2 / (2 * G) / (h0 * e ** (2 * (k + 1))) - 1)) < 1e-9
    t_zeno = t1 * (1 + e) / (1 - e)
    assert res.impacts.final_modes == {0: "contact"}
    after = res.t > t_zeno + 1e-3
    assert np.max(np.abs(res["lambda_ineq_0"][after] - G)) < 1e-9  # m g, m = 1
    assert np.max(np.abs(res["y"][after])) < 1e-9
    same_runs(runs["c"], res)


def test_fortran_ball_in_an_ensemble_and_the_integrator_object_runs_as_simulate():
    """The consumers of the impact driver take Fortran contact code alike: an ensemble's members
    (two threads) and the integrator object over the whole grid are the Fortran simulate run,
    which is the C code's."""
    t = np.linspace(0, 3, 301)
    h0 = np.array([1.0, 0.5, 2.0])
    balls = {lang: _ball(0.8, lang=lang) for lang in ("c", "fortran")}
    ball = balls["fortran"]
    ens = ball.ensemble(t, q0=h0[:, None], v0=np.zeros((3, 1)), save="trajectory", threads=2, **TIGHT)
    assert (ens.status == 0).all()
    for i, h in enumerate(h0):
        single = ball.simulate(t, q0=[h], v0=[0.0], **TIGHT)
        assert np.array_equal(ens.member(i).y, single.y)
        assert ens.member(i).impacts.records == single.impacts.records
        same_runs(balls["c"].simulate(t, q0=[h], v0=[0.0], **TIGHT), single)
    with ball.integrator(q0=[1.0], v0=[0.0], **TIGHT) as integ:
        out = integ.propagate_grid(t)
        ref = ball.simulate(t, q0=[1.0], v0=[0.0], **TIGHT)
        assert np.array_equal(out, ref.y) and integ.impacts.records == ref.impacts.records


def test_fortran_newtons_cradle_passes_the_velocity_to_the_last_ball():
    gap = 1e-3
    runs = {lang: newtons_cradle("index1", lang).simulate(np.linspace(0, 1, 11), q0=[0.0, 0.1 + gap, 0.2 + 2 * gap],
                                                   v0=[1.0, 0.0, 0.0], **TIGHT) for lang in ("c", "fortran")}
    res = runs["fortran"]
    v = res.y[-1, 3:]
    assert abs(v[0]) < 1e-12 and abs(v[1]) < 1e-12 and abs(v[2] - 1.0) < 1e-12
    assert [(r.contact, r.kind) for r in res.impacts] == [(0, "bounce"), (1, "bounce")]
    assert res.impacts[0].t == pytest.approx(gap, rel=1e-10) and res.impacts[1].t == pytest.approx(2 * gap, rel=1e-10)
    assert np.max(np.abs(res.y[:, 3:].sum(axis=1) - 1.0)) < 1e-12
    assert np.max(np.abs(res["energy"] - 0.5)) < 1e-12
    same_runs(runs["c"], res)


@pytest.mark.parametrize("alpha, mu", [(0.5, 0.6), (0.5, 0.3), (0.3, 0.31)])
def test_fortran_block_on_an_incline_sticks_when_tan_alpha_le_mu_else_slides(alpha, mu):
    t = np.linspace(0, 3, 31)
    runs = {lang: _incline(alpha, mu, lang=lang).simulate(t, q0=[0.0, 0.0], v0=[0.0, 0.0], **TIGHT)
            for lang in ("c", "fortran")}
    res = runs["fortran"]
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res["x"])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
        assert np.max(np.abs(res["lambda_t_ineq_0"] + G * math.sin(alpha))) < 1e-9
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert res.impacts.friction_modes == {0: "slip+"}
    same_runs(runs["c"], res)


@pytest.mark.parametrize("alpha, mu, beta", [(0.5, 0.6, 0.0), (0.5, 0.3, 0.7)])
def test_fortran_block_on_an_incline_in_3d_on_the_circular_cone(alpha, mu, beta):
    t = np.linspace(0, 2, 21)
    runs = {lang: _incline_3d(alpha, mu, beta, lang=lang).simulate(t, q0=[0.0] * 3, v0=[0.0] * 3, **TIGHT)
            for lang in ("c", "fortran")}
    res = runs["fortran"]
    assert np.max(np.abs(res["lambda_ineq_0"] / (G * math.cos(alpha)) - 1)) < 1e-9
    if math.tan(alpha) <= mu:
        assert np.max(np.abs(res.y[:, :3])) < 1e-12 and res.impacts.friction_modes == {0: "stick"}
    else:
        acc = G * (math.sin(alpha) - mu * math.cos(alpha))
        assert np.max(np.abs(res["x"][1:] / (0.5 * acc * t[1:] ** 2) - 1)) < 1e-9
        assert np.max(np.abs(res["y"])) < 1e-9 * np.max(res["x"])
        assert res.impacts.friction_modes == {0: "slip"}
    same_runs(runs["c"], res)


def test_fortran_sphere_on_generalized_speeds_slides_diagonally_then_rolls():
    """A quaternion sphere with 3-D friction launched along e = (3, 4) / 5 with backspin: the slip
    ends at t* = 2 (v0 + R w0) / (7 mu g), then it rolls at (5 v0 - 2 R w0) / 7 (to 1e-9); the run
    the C code's."""
    v0, w0, wz = 2.5, 3.0, 1.5
    e = np.array([0.6, 0.8])
    t_star = 2 * (v0 + RADIUS * w0) / (7 * MU * G)
    v_roll = (5 * v0 - 2 * RADIUS * w0) / 7
    t = np.linspace(0, 2 * t_star, 41)
    axis = np.array([-e[1], e[0]])
    q0, u0 = _start("quaternion", (v0 * e[0], v0 * e[1], 0), (-w0 * axis[0], -w0 * axis[1], wz))
    system = _sphere_system(MU, 0.0)
    sims = {lang: compile_constrained(system, "index1", outputs=["energy"], lang=lang) for lang in ("c", "fortran")}
    runs = {lang: sim.simulate(t, q0=q0, v0=u0, **TIGHT) for lang, sim in sims.items()}
    res, sim = runs["fortran"], sims["fortran"]
    grips = res.impacts.transitions(0)
    assert [r.kind for r in grips] == ["grip"] and grips[0].t == pytest.approx(t_star, rel=1e-9)
    rates = np.array([sim.compiled.rhs(tt, yy)[:2] for tt, yy in zip(res.t, res.y)])
    assert np.max(np.abs(rates[res.t > t_star] @ e / v_roll - 1)) < 1e-9
    same_runs(runs["c"], res)


# ---------------------------------------------------------------------- C callers, sanitizers
CALLER = r"""
#include <stdio.h>
#include "lcg_imp_model.h"

const lcg_imp_model *P_imp_model_table(void);
const lcg_imp_friction *P_imp_friction_table(void);

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
    const lcg_imp_model *im = P_imp_model_table();
    const lcg_imp_friction *fr = P_imp_friction_table();
    double p[] = PARAMS, y[NY], ydot[NY], ynew[NY], lam[NR], imp[NR], g[NC], w[NC], e[NC];
    double M[NV * NV], F[NV], R[NR * NV], s[NR], h[NR], gam[NR], qd[NQ];
    int active[NC], i, mask;

    for (i = 0; i < NY; ++i)
        y[i] = 0.3 + 0.17 * i - 0.05 * i * i;
    show("gaps", im->gaps(0.1, y, p, g, w), g, NC);
    show("normal", 0, w, NC);
    for (mask = 0; mask < (1 << NC); ++mask) {
        for (i = 0; i < NC; ++i) {
            active[i] = (mask >> i) & 1;
            e[i] = 0.25 + 0.5 * i;
        }
        show("crhs", im->crhs(0.1, y, p, 1.0, 2.0, active, ydot, lam), ydot, NY);
        show("lam", 0, lam, NR);
        show("crhs_null", im->crhs(0.1, y, p, 0.0, 0.0, active, ydot, NULL), ydot, NY);
        show("impact", im->impact(0.1, y, p, active, e, ynew, imp), ynew, NY);
        show("impulses", 0, imp, NR);
    }
    show("eval", fr->eval(0.1, y, p, M, F, R, s, h, gam, qd), M, NV * NV);
    show("eval_F", 0, F, NV);
    show("eval_R", 0, R, NR * NV);
    show("eval_sh", 0, s, NR);
    show("eval_gam", 0, gam, NR);
    show("eval_qd", 0, qd, NQ);
    return fr->imp == im && im->nk == NC && im->nrow == NR ? 0 : 3;
}
"""


def test_c_callers_of_the_fortran_contact_functions_under_sanitizers(tmp_path, cc, fc):
    """One C program (every active set, lam NULL, the friction table's numbers) linked with the C
    contact functions and with the Fortran ones and their C tables, under AddressSanitizer and
    UBSan: the same printed digits."""
    import sympy as sp
    m = lcg.Model("fsan")
    x, y = m.coordinates("x y")
    m.parameters(g=G, m=1.0)
    m.particle("b", sp.Symbol("m"), (x, y))
    m.gravity(sp.Symbol("g"))
    system = lcg.ConstrainedSystem(m, inequalities=[
        lcg.Inequality(y, restitution=0.2, tangent=x, friction=0.4), lcg.Inequality(2 - x, restitution=0.5)])
    san = ["-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
    outputs = {}
    for lang in ("c", "fortran"):
        folder = tmp_path / lang
        code, info = generate_constrained(system, lang=lang)
        code.write(folder)
        pre = info.prefix
        from lagcodegen.build import dae_table_source, table_source
        for fname, text in {**dae_table_source(code), **table_source(code)}.items():
            (folder / fname).write_text(text)
        sizes = {"NY": 4, "NQ": 2, "NV": 2, "NC": 2, "NR": 3}
        main = CALLER.replace("P_", f"{pre}_").replace("PARAMS", "{%r, %r}" % tuple(code.param_defaults))
        main = "".join(f"#define {k} {v}\n" for k, v in sizes.items()) + main
        (folder / "main.c").write_text(main)
        c_files = sorted(n for n in code.files if n.endswith(".c")) + [f"{pre}_dae_table.c", f"{pre}_table.c"]
        objects = []
        if lang == "fortran":
            sources = [f"{pre}.f90", f"{pre}_dae.f90", f"{pre}_impact.f90"]
            proc = subprocess.run([fc, *san, "-ffp-contract=off", *STRICT_FFLAGS, "-c", *sources], cwd=folder,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr
            objects = [n[:-4] + ".o" for n in sources] + ["-lgfortran"]
        proc = subprocess.run([cc, *san, "-std=c99", "main.c", *c_files, *objects, "-o", "main", "-lm"], cwd=folder,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        run = subprocess.run(["./main"], cwd=folder, capture_output=True, text=True,
                             env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
        assert run.returncode == 0, run.stdout + run.stderr
        assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr
        outputs[lang] = run.stdout
    lines = outputs["c"].splitlines()
    assert len(lines) == 2 + 5 * 4 + 6 and all(" rc=0" in line for line in lines)
    if BIT_IDENTICAL:
        assert outputs["fortran"] == outputs["c"]
    else:
        for a, b in zip(lines, outputs["fortran"].splitlines()):
            np.testing.assert_allclose(np.array(b.split()[2:], float), np.array(a.split()[2:], float), rtol=1e-12,
                                       atol=1e-14)
