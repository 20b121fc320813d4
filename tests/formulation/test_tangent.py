"""The tangent-form Jacobian and the program form of large kernels (lagcodegen.formulation.tangent,
lagcodegen.codegen.c): the expanded Jacobian's values to round-off, central differences of the
right-hand side, the classic one-function right-hand side's values, strict C (also cut into pieces
of a few statements, so that every path across pieces runs), the same CVODE BDF results, code
that grows like n^2 and functions of bounded length."""

import re
import subprocess

import numpy as np
import pytest

from lagcodegen import Scene, build_code, derive, generate_c, systems
from lagcodegen.errors import ModelError
from lagcodegen.formulation.kernels import model_blocks
from lagcodegen.formulation.scene import auto_jacobian_form
from lagcodegen.formulation.tangent import tangent_program
from lagcodegen.theory.routhian import reduce

from helpers import STRICT_CFLAGS


def routhian_eom():
    return reduce(systems.spherical_pendulum("tg_routh")).eom


def folded_and_runtime():
    """A double pendulum with l1, m2 folded (one of them to a non-integer value) and the rest run-time."""
    return derive(systems.n_link_pendulum(3, name="tg_fold", shared_parameters=False))


CASES = {
    "pendulum": (lambda: derive(systems.pendulum("tg_pend")), {}),
    "double_pendulum": (lambda: derive(systems.double_pendulum("tg_dp")), {}),
    "n_link4": (lambda: derive(systems.n_link_pendulum(4, name="tg_n4")), {}),
    # Large enough for blocks of wide statements of several column sets (program form: the tangent
    # Jacobian always; the right-hand side from PROGRAM_MIN_OPS, 17 links since the point-mass derivation).
    "n_link10": (lambda: derive(systems.n_link_pendulum(10, name="tg_n10")), {}),
    "spring_chain": (lambda: derive(systems.spring_chain(6, 1e3, name="tg_chain")), {}),
    "spherical": (lambda: derive(systems.spherical_pendulum("tg_sph")), {}),
    "routhian": (routhian_eom, {}),
    "folded": (folded_and_runtime, dict(runtime_parameters=["g", "m1", "l3"], values={"l1": 0.7, "m2": 2.0})),
}


#: The models simulated with CVODE (the others are built without the native driver).
SIMULATED = ("double_pendulum", "spring_chain")


def compiled(name, form, tag=""):
    make, opts = CASES[name]
    return build_code(generate_c(Scene(make(), jacobian_form=form, prefix=f"tg_{name}_{form}{tag}", **opts)),
                 native=name in SIMULATED)


@pytest.fixture(scope="module")
def models():
    return {name: {form: compiled(name, form) for form in ("expanded", "tangent")} for name in CASES}


@pytest.fixture()
def tiny_pieces(monkeypatch):
    """The program form everywhere (right-hand side, expanded Jacobian), cut into pieces of at most
    3 statements: values, narrow tangents and wide tangents cross pieces."""
    import lagcodegen.codegen.c as cmod
    monkeypatch.setattr(cmod, "PROGRAM_MIN_OPS", 0)
    monkeypatch.setattr(cmod, "CHUNK_STATEMENTS", 3)


@pytest.mark.parametrize("name", sorted(CASES))
def test_tangent_equals_expanded_and_differences(models, name):
    exp, tan = models[name]["expanded"], models[name]["tangent"]
    rng = np.random.default_rng(7)
    for _ in range(3):
        y = rng.uniform(-1.0, 1.0, tan.ny) + 0.3
        Je, Jt = exp.jac(0.4, y), tan.jac(0.4, y)
        scale = max(1.0, np.abs(Je).max())
        assert np.abs(Jt - Je).max() <= 1e-13 * scale
        h, Jd = 1e-6, np.zeros_like(Jt)
        for j in range(tan.ny):
            e = np.zeros(tan.ny)
            e[j] = h
            Jd[:, j] = (tan.rhs(0.4, y + e) - tan.rhs(0.4, y - e)) / (2 * h)
        assert np.abs(Jt - Jd).max() <= 1e-6 * scale


def test_quadrature_rows_are_differentiated(models):
    tan = models["routhian"]["tangent"]
    assert tan.code.nz == 1
    p = np.full(len(tan.param_names), 1.3)  # C_phi != 0
    J = tan.jac(0.1, np.array([0.7, 0.2, 0.0]), p)
    assert np.all(J[2, :1] != 0.0)  # d phi' / d theta
    assert np.allclose(J, models["routhian"]["expanded"].jac(0.1, np.array([0.7, 0.2, 0.0]), p), rtol=1e-13, atol=0)


@pytest.mark.parametrize("name", ["routhian", "folded"])
def test_tangent_c_compiles_with_strict_warnings(tmp_path, cc, name):
    make, opts = CASES[name]
    code = generate_c(Scene(make(), jacobian_form="tangent", outputs=["energy"], prefix=f"tgs_{name}", **opts))
    assert "call_start[j]" in code.files[code.source_name]
    code.write(tmp_path)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", code.source_name, "-o", "m.o"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_constant_mass_and_no_force_compile_strict(tmp_path, cc):
    from lagcodegen import Model
    m = Model("tg_free")
    x, = m.coordinates("x")
    m.kinetic_energy(m.dot(x) ** 2 / 2)
    code = generate_c(Scene(derive(m), jacobian_form="tangent"))
    code.write(tmp_path)
    proc = subprocess.run([cc, *STRICT_CFLAGS, "-c", code.source_name, "-o", "m.o"], cwd=tmp_path,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_bdf_results_match(models):
    t = np.linspace(0.0, 2.0, 21)
    runs = {form: models["spring_chain"][form].simulate(t, q0=[0.1, 0.1, 0, 0, 0, 0], v0=[0] * 6, method="bdf",
                                                        rtol=1e-9, atol=1e-11)
            for form in ("expanded", "tangent")}
    assert runs["tangent"].stats["jac_evals"] > 0
    assert np.abs(runs["tangent"].y - runs["expanded"].y).max() < 1e-8
    dp = {form: models["double_pendulum"][form].simulate(t, q0=[1.0, 0.5], v0=[0, 0], method="bdf",
                                                        rtol=1e-10, atol=1e-12)
          for form in ("expanded", "tangent")}
    assert np.abs(dp["tangent"].y - dp["expanded"].y).max() < 1e-8


def test_tangent_code_grows_like_n_squared():
    sizes = {}
    for n in (4, 8, 16):
        rhs = model_blocks(Scene(derive(systems.n_link_pendulum(n, name=f"tgg{n}")), jacobian=False))["rhs"]
        sizes[n] = tangent_program(rhs, n).size()
    assert sizes[16] / sizes[8] < 2 ** 2.4 and sizes[8] / sizes[4] < 2 ** 2.4


def test_jacobian_form_option():
    eom = derive(systems.double_pendulum("tg_opt"))
    with pytest.raises(ModelError, match="jacobian_form"):
        Scene(eom, jacobian_form="reverse")
    assert auto_jacobian_form(2) == "expanded" and auto_jacobian_form(30) == "tangent"
    assert Scene(eom, jacobian_form="tangent").resolved_jacobian_form() == "tangent"
    expanded = generate_c(Scene(eom, jacobian_form="expanded"))
    assert generate_c(Scene(eom)).files == expanded.files  # auto keeps small models expanded
    assert "call_start[j]" not in expanded.files[expanded.source_name]


@pytest.mark.parametrize("name,eliminate", [("n_link4", True), ("spring_chain", True), ("routhian", True),
                                             ("folded", True), ("n_link4", False), ("folded", False)])
def test_tiny_pieces_give_the_same_values(models, tiny_pieces, monkeypatch, name, eliminate):
    """eliminate=False: the programs by hash-consing alone, as for the largest models."""
    exp, tan = models[name]["expanded"], models[name]["tangent"]
    if not eliminate:
        import lagcodegen.codegen.c as cmod
        import lagcodegen.formulation.tangent as tmod
        monkeypatch.setattr(cmod, "BLOCK_CSE_MAX_OPS", 0)
        monkeypatch.setattr(tmod, "CSE_MAX_OPS", 0)
    tag = "_pieces" if eliminate else "_hashed"
    pieces = {form: compiled(name, form, tag) for form in ("expanded", "tangent")}
    assert "NOINLINE void values" in pieces["expanded"].code.files[pieces["expanded"].code.source_name]
    rng = np.random.default_rng(3)
    for _ in range(2):
        y = rng.uniform(-1.0, 1.0, tan.ny) + 0.3
        f = exp.rhs(0.2, y)
        Je = exp.jac(0.2, y)
        scale = max(1.0, np.abs(Je).max())
        for cm in pieces.values():
            assert np.abs(cm.rhs(0.2, y) - f).max() <= 1e-13 * max(1.0, np.abs(f).max())
            assert np.abs(cm.jac(0.2, y) - Je).max() <= 1e-13 * scale


@pytest.mark.parametrize("name", ["routhian", "folded", "spring_chain"])
def test_tiny_pieces_compile_with_strict_warnings(tmp_path, cc, tiny_pieces, name):
    make, opts = CASES[name]
    for form in ("expanded", "tangent"):
        code = generate_c(Scene(make(), jacobian_form=form, outputs=["energy"], prefix=f"tgp_{name}_{form}", **opts))
        code.write(tmp_path)
        for level in ("-O0", "-O2"):
            proc = subprocess.run([cc, *STRICT_CFLAGS, level, "-c", code.source_name, "-o", "m.o"], cwd=tmp_path,
                                  capture_output=True, text=True)
            assert proc.returncode == 0, proc.stderr


def test_large_kernels_come_in_short_functions():
    """The compiler's time grows like the code's size only if no function grows with n: every
    function of the program form holds at most CHUNK_STATEMENTS statements (or CHUNK_CHARS)."""
    from lagcodegen.codegen.c import CHUNK_CHARS, CHUNK_STATEMENTS
    eom = derive(systems.n_link_pendulum(18, name="tg_short"))  # a right-hand side of >= PROGRAM_MIN_OPS
    for form in ("expanded", "tangent"):
        src = generate_c(Scene(eom, jacobian_form=form)).files["tg_short.c"]
        bodies = re.findall(r"^(?:static|PIECE) NOINLINE void \w+\([^)]*\)\n\{\n(.*?)^\}", src, re.S | re.M)
        assert len(bodies) > 10
        for body in bodies:
            lines = body.splitlines()[1:]  # the (void) casts first
            assert len(lines) <= CHUNK_STATEMENTS or sum(map(len, lines)) <= CHUNK_CHARS + max(map(len, lines))
        # rhs and jac themselves: calls and short loops, not the kernel's statements
        for fn in ("rhs", "jac"):
            body = re.search(rf"^int tg_short_{fn}\(.*?^\}}", src, re.S | re.M).group(0)
            assert body.count("\n") < 200


def test_program_form_rhs_equals_the_one_function_form(monkeypatch):
    """The right-hand side of a large model (program form: hash-consed statements in pieces)
    against the same scene printed as one function (symengine's elimination), to round-off."""
    import lagcodegen.codegen.c as cmod
    eom = derive(systems.n_link_pendulum(18, name="tg_prog"))  # >= PROGRAM_MIN_OPS operations
    program = build_code(generate_c(Scene(eom, jacobian=False, prefix="tg_prog_pieces")), native=False)
    assert "NOINLINE void values" in program.code.files[program.code.source_name]
    monkeypatch.setattr(cmod, "PROGRAM_MIN_OPS", 10 ** 9)
    single = build_code(generate_c(Scene(eom, jacobian=False, prefix="tg_prog_single")), native=False)
    assert "NOINLINE" not in single.code.files[single.code.source_name]
    rng = np.random.default_rng(11)
    for _ in range(3):
        y = rng.uniform(-1.0, 1.0, single.ny)
        f = single.rhs(0.0, y)
        assert np.abs(program.rhs(0.0, y) - f).max() <= 1e-12 * max(1.0, np.abs(f).max())
