"""Generated C: strict warnings, sanitizers, what the scene asks for and nothing more."""

import subprocess

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen import Scene, derive, generate_c, systems
from lagcodegen.build import driver_sources, find_sundials

from helpers import STRICT_CFLAGS

MODELS = {
    "pendulum": systems.pendulum,
    "double_pendulum": systems.double_pendulum,
    "oscillator": systems.damped_driven_oscillator,
    "central": systems.central_potential,
    "chain5": lambda: systems.n_link_pendulum(5),
}


def code_for(name, **scene):
    return generate_c(Scene(derive(MODELS[name]()), **scene))


@pytest.mark.parametrize("name", sorted(MODELS))
def test_generated_c_compiles_with_strict_warnings(tmp_path, cc, name):
    code = code_for(name, outputs=["energy", "momenta", "positions"])
    code.write(tmp_path)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", code.source_name, "-o", "m.o"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("opt", ["-O2", "-O3", "-O1 -DLCG_COLD_JACOBIAN"])
@pytest.mark.parametrize("name", ["pendulum", "central_potential", "spring_chain"])
def test_generated_c_compiles_strictly_when_optimized(tmp_path, cc, name, opt):
    """Optimizers see more (inlined solves, array bounds, uninitialized reads): embedders build
    with -O2 -Werror; lagcodegen's own builds at MODEL_CFLAGS (-O1, the Jacobian at -O0). One coordinate (a 1 x 1 system), a diagonal M, a chain with the sparse
    Jacobian."""
    model = getattr(systems, name)(*((4, 1e3) if name == "spring_chain" else ()))
    code = generate_c(Scene(derive(model), outputs=["energy"], sparse_jacobian=True))
    code.write(tmp_path)
    for source in (code.source_name, f"{code.prefix}_sparse.c"):
        proc = subprocess.run([cc, *opt.split(), *STRICT_CFLAGS, "-c", source, "-o", "m.o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_native_driver_compiles_with_strict_warnings(tmp_path, cc):
    code = code_for("double_pendulum", outputs=["energy"])
    code.write(tmp_path)
    for fname, text in driver_sources(code, find_sundials()).items():
        (tmp_path / fname).write_text(text)
    for source in ("lcg_cvode.c", f"{code.prefix}_table.c"):  # the model-independent driver, the table
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", source, "-o", "d.o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


SANITIZER_MAIN = r"""
#include <math.h>
#include <stdio.h>
#include "PREFIX.h"
#include "lcg_cvode.h"

extern const lcg_model PREFIX_model;

int main(void)
{
    double y[PREFIXU_NY], ydot[PREFIXU_NY], jac[PREFIXU_NY * PREFIXU_NY], out[PREFIXU_NOUT + 1];
    double p[PREFIXU_NP + 1];
    double tout[51], yout[51 * PREFIXU_NY], outs[51 * (PREFIXU_NOUT + 1)];
    lcg_cvode_options opt = {1, 1, 1e-8, 1e-10, NULL, 100000, 0.0, 0.0, 0.0, 0};
    lcg_cvode_stats st;
    int i, rc = 0;

    for (i = 0; i < PREFIXU_NP; ++i)
        p[i] = PARAMS[i];
    for (i = 0; i < PREFIXU_NY; ++i)
        y[i] = 1.0 + 0.1 * i;
    rc |= PREFIX_rhs(0.1, y, p, ydot);
    rc |= PREFIX_jac(0.1, y, ydot, p, jac);
    rc |= PREFIX_outputs(0.1, y, p, out);
    for (i = 0; i < 51; ++i)
        tout[i] = 0.1 * i;
    rc |= lcg_cvode_solve(&PREFIX_model, p, y, 51, tout, yout, outs, &opt, &st);
    printf("rc=%d steps=%ld y_end=%.17g energy0=%.17g energy_end=%.17g\n", rc, st.nsteps,
           yout[50 * PREFIXU_NY], outs[0], outs[50 * PREFIXU_NOUT]);
    return rc != 0 || st.nt_done != 51;
}
"""


@pytest.mark.parametrize("name", ["double_pendulum", "central"])
def test_generated_code_and_driver_clean_under_sanitizers(tmp_path, cc, name):
    code = code_for(name, outputs=["energy"])
    sundials = find_sundials()
    code.write(tmp_path)
    for fname, text in driver_sources(code, sundials).items():
        (tmp_path / fname).write_text(text)
    params = ", ".join(repr(v) for v in code.param_defaults) or "0.0"
    main = (SANITIZER_MAIN.replace("PREFIXU", code.prefix.upper()).replace("PREFIX", code.prefix)
            .replace("PARAMS", f"((const double[]){{{params}}})"))
    (tmp_path / "main.c").write_text(main)
    cmd = [cc, "-g", "-O1", "-std=c99", "-fsanitize=address,undefined", "-fno-sanitize-recover=all",
           "main.c", code.source_name, f"{code.prefix}_table.c", "lcg_cvode.c", "lcg_inputs.c", "-o", "main",
           "-pthread", *sundials.link_args(), "-lm"]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    run = subprocess.run(["./main"], cwd=tmp_path, capture_output=True, text=True,
                         env={"ASAN_OPTIONS": "detect_leaks=1", "UBSAN_OPTIONS": "print_stacktrace=1"})
    assert run.returncode == 0, run.stdout + run.stderr
    assert "runtime error" not in run.stderr and "AddressSanitizer" not in run.stderr
    fields = dict(kv.split("=") for kv in run.stdout.split())
    assert abs(float(fields["energy_end"]) - float(fields["energy0"])) < 1e-6


def test_scene_emits_only_what_it_asks_for():
    eom = derive(systems.double_pendulum())
    bare = generate_c(Scene(eom, jacobian=False))
    src = bare.files[bare.source_name]
    assert "double_pendulum_rhs" in src
    assert "double_pendulum_jac" not in src and "double_pendulum_outputs" not in src
    full = generate_c(Scene(eom, outputs=["energy"]))
    assert "double_pendulum_jac" in full.files[full.source_name]
    assert full.output_names == ["energy"]


def test_folded_parameters_become_constants():
    eom = derive(systems.double_pendulum())
    code = generate_c(Scene(eom, runtime_parameters=["g"], values={"l2": 0.7}))
    src = code.files[code.source_name]
    assert code.param_names == ["g"]
    assert "p[0]" in src and "p[1]" not in src
    assert "0.7*" in src or "*0.7" in src  # l2 = 0.7 folded (repr: the shortest exact text)
    header = code.files[code.header_name]
    assert "p[0] = g" in header and "l2 = 0.7" in header


def test_constants_are_printed_exactly():
    import random
    import re
    import symengine as se
    from lagcodegen.codegen.c import c_expr
    rng = random.Random(3)
    for _ in range(2000):
        x = rng.uniform(-1, 1) * 10.0 ** rng.randint(-300, 300)
        text = c_expr(se.RealDouble(x) * se.Symbol("y[0]") + se.Symbol("t"))
        number = re.search(r"\(?(-?[0-9.]+(?:e[+-]?[0-9]+)?)\)?\*y\[0\]|y\[0\]\*\(?(-?[0-9.]+(?:e[+-]?[0-9]+)?)\)?", text)
        assert number, text
        assert float(number.group(1) or number.group(2)) == x
    assert c_expr(se.Integer(10**20) * se.Symbol("t")) in ("1e+20*t", "t*1e+20")


def test_folded_and_runtime_parameters_give_the_same_numbers():
    eom = derive(systems.double_pendulum())
    folded = lcg.build_code(generate_c(Scene(eom, runtime_parameters=[], values={"m2": 2.5}, prefix="dpf")))
    runtime = lcg.build_code(generate_c(Scene(eom, prefix="dpr")))
    y = np.array([0.4, -1.1, 0.3, 0.8])
    p = runtime.parameter_vector({"m2": 2.5})
    np.testing.assert_allclose(folded.rhs(0.0, y), runtime.rhs(0.0, y, p), rtol=1e-14)
    np.testing.assert_allclose(folded.jac(0.0, y), runtime.jac(0.0, y, p), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_jacobian_matches_central_differences(name):
    cm = lcg.build_code(code_for(name, prefix=f"fd_{name}"))
    rng = np.random.default_rng(1)
    y = rng.uniform(0.2, 1.0, cm.ny)
    J = cm.jac(0.3, y)
    eps = 1e-6
    Jfd = np.column_stack([(cm.rhs(0.3, y + eps * e) - cm.rhs(0.3, y - eps * e)) / (2 * eps)
                           for e in np.eye(cm.ny)])
    np.testing.assert_allclose(J, Jfd, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(Jfd).max()))


def test_rhs_matches_symbolic_solve():
    # The numeric M q'' = F solve equals sympy's solution of the same linear system.
    eom = derive(systems.double_pendulum())
    cm = lcg.build_code(generate_c(Scene(eom, prefix="dp_sym")))
    y = [0.7, -0.2, 1.3, 0.4]
    subs = dict(zip(eom.q + eom.qd, y))
    subs.update({s: v for s, v in eom.parameters.items()})
    acc = eom.M.subs(subs).evalf().LUsolve(eom.F.subs(subs).evalf())
    np.testing.assert_allclose(cm.rhs(0.0, y)[2:], np.array(acc, dtype=float).ravel(), rtol=1e-13)


def test_mass_matrix_that_is_not_positive_definite_uses_lu():
    # M = diag(-1, 1)-like Lagrangian (indefinite but regular): LU fallback must solve it.
    model = lcg.Model("indef")
    x, y = model.coordinates("x y")
    model.kinetic_energy(-model.dot(x) ** 2 / 2 + model.dot(y) ** 2 / 2 + model.dot(x) * model.dot(y) / 4)
    model.potential_energy(x**2 / 2 + y**2 / 2 + x * y / 3)
    eom = derive(model)
    cm = lcg.build_code(generate_c(Scene(eom)))
    state = np.array([0.3, -0.5, 0.1, 0.2])
    M = np.array(eom.M, dtype=float)
    F = np.array(eom.F.subs(dict(zip(eom.q + eom.qd, state))), dtype=float).ravel()
    np.testing.assert_allclose(cm.rhs(0.0, state)[2:], np.linalg.solve(M, F), rtol=1e-13)
