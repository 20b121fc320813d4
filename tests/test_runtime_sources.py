"""The runtime's C as real files, its structs declared once, its result codes in one table.

* lagcodegen/runtime/ holds C that compiles as it is (no template syntax), and the runtime's cache
  key follows every file's text;
* the C ``#define`` s of lcg_codes.h carry the values of lagcodegen.codes, and the C drivers and
  the Python runners share its rule for non-finite values;
* the generated struct headers, the cffi declarations and the Python pack formats come from one
  declaration, and cffi refuses a declaration that disagrees with the compiled header.
"""

from __future__ import annotations

import importlib
import re
import shutil
import subprocess

import cffi
import pytest

import lagcodegen.runtime as runtime_package
from lagcodegen.codegen import signatures as sig
from lagcodegen.codegen.cffi_decl import runtime_cdef, taylor_runtime_cdef
from lagcodegen.codes import FLAG_TEXT, NONFINITE_CAUSES, SOLVER_FLAG_TEXT, Flag, ModelCode, c_header, \
    model_error_flag
from lagcodegen.solvers import base, control, ensemble_result
from lagcodegen.solvers.cvode import native as cvode
from lagcodegen.solvers.ida import native as ida
from lagcodegen.codegen.taylor.emit import runtime_sources as taylor_runtime_sources

from helpers import STRICT_CFLAGS

B = importlib.import_module("lagcodegen.build")


def test_runtime_files_are_plain_c_and_compile_strictly(tmp_path, cc):
    files = sorted(p.name for p in runtime_package.FOLDER.iterdir() if p.suffix in (".c", ".h"))
    assert {"lcg_cvode.c", "lcg_cvc.c", "lcg_ida.c", "lcg_taylor.c", "lcg_pool.h", "lcg_control.h"} <= set(files)
    for name in files:
        text = runtime_package.source(name)
        assert "{{" not in text and "{%" not in text, f"{name} holds template syntax"
    sources = {**B.runtime_sources(B.find_sundials()), **taylor_runtime_sources()}
    for name, text in sources.items():
        (tmp_path / name).write_text(text)
    for name in ("lcg_cvode.c", "lcg_cvc.c", "lcg_ida.c", "lcg_taylor.c"):
        proc = subprocess.run([cc, *STRICT_CFLAGS, "-O2", "-c", name, "-o", name[:-2] + ".o"], cwd=tmp_path,
                              capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr


def test_runtime_key_follows_every_runtime_file(tmp_path, monkeypatch, cc):
    sundials = B.find_sundials()
    before = B.runtime_key(cc, B.DEFAULT_CFLAGS, sundials)
    assert B.runtime_key(cc, B.DEFAULT_CFLAGS, sundials) == before
    for name in ("lcg_pool.h", "lcg_cvode.c", "sundials_api.h"):
        folder = tmp_path / name
        shutil.copytree(runtime_package.FOLDER, folder, ignore=shutil.ignore_patterns("*.py", "__pycache__"))
        (folder / name).write_text((folder / name).read_text() + "\n/* changed */\n")
        monkeypatch.setattr(runtime_package, "FOLDER", folder)
        assert B.runtime_key(cc, B.DEFAULT_CFLAGS, sundials) != before, name
        monkeypatch.undo()
    # and the generated headers: a changed declaration changes the key
    monkeypatch.setattr(sig, "CVODE_STATS", sig.Struct("lcg_cvode_stats", sig.CVODE_STATS.fields[:-1]))
    monkeypatch.setitem(sig.DRIVERS, "cvode", sig.Driver("cvode", "lcg_model.h", (
        sig.CVODE_OPTIONS, sig.CVODE_STATS, sig.ensemble("lcg_cvode_ensemble", "lcg_model"))))
    assert B.runtime_key(cc, B.DEFAULT_CFLAGS, sundials) != before


def _c_values(tmp_path, cc, exprs: list[str]) -> list[int]:
    (tmp_path / "lcg_codes.h").write_text(c_header())
    body = "".join(f'    printf("%d\\n", (int)({e}));\n' for e in exprs)
    (tmp_path / "main.c").write_text(f'#include <stdio.h>\n#include "lcg_codes.h"\nint main(void)\n{{\n{body}'
                                     "    return 0;\n}\n")
    subprocess.run([cc, *STRICT_CFLAGS, "main.c", "-o", "main"], cwd=tmp_path, check=True)
    out = subprocess.run(["./main"], cwd=tmp_path, capture_output=True, text=True, check=True).stdout
    return [int(v) for v in out.split()]


def test_c_codes_are_the_python_table(tmp_path, cc):
    names = [f"LCG_FLAG_{f.name}" for f in Flag] + ["LCG_OK", "LCG_ERR_SINGULAR_MASS", "LCG_ERR_NONFINITE",
                                                      "LCG_DAE_OK", "LCG_DAE_ERR_SINGULAR", "LCG_DAE_ERR_NONFINITE",
                                                      "LCG_DAE_ERR_PROJECTION", "LCG_MODEL_ERROR_FLAG(2)"]
    expected = [int(f) for f in Flag] + [0, 1, 2, 0, 1, 2, 3, model_error_flag(ModelCode.NONFINITE)]
    assert _c_values(tmp_path, cc, names) == expected
    assert model_error_flag(ModelCode.NONFINITE) == -102
    # the attribution rule of non-finite values: the C macro and the scikit-sundae runner's tuple
    flags = list(range(-40, 1))
    got = _c_values(tmp_path, cc, [f"LCG_CVODE_NONFINITE_CAUSE({f})" for f in flags])
    assert [f for f, v in zip(flags, got) if v] == sorted(NONFINITE_CAUSES["CVODE"])


def test_python_reads_the_one_table():
    assert (base.ERR_SINGULAR, base.ERR_NONFINITE, base.ERR_PROJECTION) == (1, 2, 3)
    assert base.FLAG_TEXT is SOLVER_FLAG_TEXT
    assert (control.CANCELLED, control.TIMED_OUT, control.NOT_RUN, control.CHUNK_FAILED) == (-80, -81, -82, -83)
    assert ensemble_result.REJECTED == -84
    for flag, text in ensemble_result.FLAG_TEXT.items():
        assert FLAG_TEXT[flag] == text
    assert SOLVER_FLAG_TEXT["Taylor"][-20] == "out of memory"
    assert base.message(-20, 0, "", "Taylor") == "out of memory"


def test_runtime_c_has_no_literal_flags():
    """Every driver flag in the runtime's C is a name of lcg_codes.h (comments aside)."""
    for name in ("lcg_cvode.c", "lcg_cvc.c", "lcg_ida.c", "lcg_taylor.c", "lcg_pool.h", "lcg_control.h",
                 "lcg_sundials.h"):
        code = re.sub(r"/\*.*?\*/", "", runtime_package.source(name), flags=re.S)
        literal = re.findall(r"-\s*(?:2[0-2]|8[0-4]|100)\b", code)
        assert not literal, f"{name}: literal flags {literal}"


def test_pack_formats_and_stat_names_come_from_the_declaration():
    assert cvode.CVC_OPTIONS[1] == sig.pack_format(sig.CVC_OPTIONS, cvode.CVC_OPTIONS[0]) == "idqdddiddidiid"
    assert ida.IDA_OPTIONS[1] == sig.pack_format(sig.IDA_OPTIONS, ida.IDA_OPTIONS[0]) == "dqdddiiiiid"
    assert base.STAT_NAMES == sig.STAT_NAMES
    assert list(base.STAT_NAMES)[:3] == ["nsteps", "njac", "nlinsetups"]
    with pytest.raises(KeyError, match="no field 'nope'"):
        sig.pack_format(sig.CVC_OPTIONS, ("rtol", "nope"))


def test_every_declared_struct_is_in_the_cffi_interface():
    rt, taylor = runtime_cdef(), taylor_runtime_cdef()
    for name, driver in sig.DRIVERS.items():
        for struct in driver.structs:
            assert sig.cffi_struct(struct) in (taylor if name == "taylor" else rt), struct.name
    for table, cdef in ((sig.MODEL_TABLE, rt), (sig.DAE_TABLE, rt), (sig.TAYLOR_TABLE, taylor)):
        assert sig.cffi_struct(table) in cdef


def test_generated_header_and_cffi_agree_and_cffi_refuses_a_wrong_declaration(tmp_path):
    header = sig.c_header(sig.Driver("probe", "stddef.h", (sig.CVODE_STATS,)), "test").replace(
        '#include "stddef.h"', "#include <stddef.h>")
    (tmp_path / "probe.h").write_text(header)

    def build(struct, name):
        ffi = cffi.FFI()
        ffi.cdef(sig.cffi_struct(struct) + "\nsize_t probe_size(void);")
        ffi.set_source(name, '#include "probe.h"\nsize_t probe_size(void) { return sizeof(lcg_cvode_stats); }',
                       include_dirs=[str(tmp_path)])
        ffi.compile(tmpdir=str(tmp_path))
        module = importlib.import_module(name)
        return module

    import sys
    sys.path.insert(0, str(tmp_path))
    try:
        good = build(sig.CVODE_STATS, "_lcg_probe_good")
        assert good.ffi.sizeof("lcg_cvode_stats") == good.lib.probe_size()
        assert good.ffi.offsetof("lcg_cvode_stats", "message") == good.ffi.sizeof("long") * 8 + 8 * 2 + 4 * 3
        swapped = list(sig.CVODE_STATS.fields)
        swapped[0], swapped[1] = swapped[1], swapped[0]  # same size, another order: a wrong layout
        with pytest.raises(Exception, match="wrong offset for field .nrhs."):
            bad = build(sig.Struct("lcg_cvode_stats", tuple(swapped)), "_lcg_probe_bad")
            bad.ffi.new("lcg_cvode_stats *")
    finally:
        sys.path.remove(str(tmp_path))


def test_c_struct_renders_every_field_in_order():
    text = sig.c_struct(sig.IDA_OPTIONS)
    at = [text.find("    " + f.c() + ";") for f in sig.IDA_OPTIONS.fields]
    assert -1 not in at and at == sorted(at)
    assert sig.Field("poll", "int (*)(void *data)").c() == "int (*poll)(void *data)"
    assert sig.Field("message", "char[512]").c() == "char message[512]"
    assert sig.Field("p", "const double *").c() == "const double *p"
    assert "    /* run control (all zero: none) */\n    int *cancel;" in text
    assert all(len(line) <= 110 for line in text.splitlines())


def test_taylor_event_location_is_one_file_for_both_drivers():
    """lcg_taylor_roots.h is printed as it is into a standalone integrator with events, and
    included by the runtime's driver (one source, two uses)."""
    import sympy as sp

    import lagcodegen as lcg
    from lagcodegen.model.events import Event
    from lagcodegen.codegen.taylor.emit import taylor_sources

    roots = runtime_package.source("lcg_taylor_roots.h")
    scene = lcg.Scene(lcg.derive(lcg.systems.pendulum()), jacobian=False)
    with_events = taylor_sources(scene, [Event("down", sp.Symbol("theta"), 0, False)])["pendulum_taylor.c"]
    assert roots in with_events and "#include \"lcg_taylor_roots.h\"" not in with_events
    assert roots not in taylor_sources(scene)["pendulum_taylor.c"]  # no events: no root finding
    runtime = taylor_runtime_sources()
    assert runtime["lcg_taylor_roots.h"] == roots
    assert '#include "lcg_taylor_roots.h"' in runtime["lcg_taylor_driver.h"]
    assert roots not in runtime["lcg_taylor_driver.h"]


def test_taylor_step_rules_are_one_text_for_both_drivers():
    """The standalone integrator's step rules (Horner, step size, tolerance, order, the jet entry
    point) and its event location are printed from the runtime's lcg_taylor_driver.h: an edit of
    a rule there shows in <prefix>_taylor.c, and what only the runtime does (the table, relative
    tolerances by blocks) does not."""
    import sympy as sp

    import lagcodegen as lcg
    from lagcodegen.model.events import Event
    from lagcodegen.codegen.taylor import emit

    scene = lcg.Scene(lcg.derive(lcg.systems.pendulum()), jacobian=False)
    text = emit.taylor_sources(scene, [Event("down", sp.Symbol("theta"), 0, False)])["pendulum_taylor.c"]
    header = runtime_package.source("lcg_taylor_driver.h")
    assert "static double tl_step_size(const double *X, int p, const pendulum_taylor_options *opt, " \
           "const double sf[2])\n" in text
    assert "int pendulum_taylor_jet(double t, const double *y, const double *p, int order, double *jet)\n" in text
    for runtime_only in ("lcg_taylor_model", "LCG_TAYLOR_RUNTIME", "rel_block", "tl_table_ok", "shared with"):
        assert runtime_only in header and runtime_only not in text, runtime_only
    for rule in ("h = tl_step_size(", "tl_eval(X, order, tau[j], ev->y", "if (te - last[e] <= 1e-9 * h",
                 "sf[j] = pow(fmin(exp(-0.7 / (p - 1)), cap), -(double)(p - j));"):
        assert rule in text
    # one source: a rule changed in the runtime's file is the standalone integrator's rule
    edited = header.replace("exp(-0.7 / (p - 1))", "exp(-0.6 / (p - 1))")
    assert edited != header
    real = emit.runtime_file
    try:
        emit.runtime_file = lambda name: edited if name == "lcg_taylor_driver.h" else real(name)
        part = emit.driver_section("rules", options_type="pendulum_taylor_options", jet_name="pendulum_taylor_jet")
    finally:
        emit.runtime_file = real
    assert "exp(-0.6 / (p - 1))" in part and part.replace("0.6", "0.7") in text
    with pytest.raises(lcg.LagcodegenError, match="no part 'steps'"):
        emit.driver_section("steps", options_type="x")


def test_model_headers_declare_the_declared_signatures():
    """The prototypes of a generated model's header (plain and constrained) are those of
    MODEL_FUNCTIONS and DAE_FUNCTIONS, whose pointer types the runtime's tables (and their cffi
    declarations) are made of."""
    import lagcodegen as lcg
    from lagcodegen.codegen.constrained import generate_constrained
    from lagcodegen.theory.constraints import ConstrainedSystem

    m = lcg.Model("cart")
    x, y = m.coordinates("x y")
    length, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
    m.particle("bob", mass, (x, y))
    m.gravity(g)
    code, _ = generate_constrained(ConstrainedSystem(m, holonomic=[x**2 + y**2 - length**2]), ggl=True)
    flat = {name: " ".join(text.split()) for name, text in code.files.items() if name.endswith(".h")}
    dae = flat["cart_dae.h"]
    for name, s in sig.DAE_FUNCTIONS.items():
        if name == "roots":
            continue  # declared only by models with events
        assert s.c("cart") + ";" in dae, name
    assert sig.MODEL_FUNCTIONS["rhs"].c("cart") + ";" in flat["cart.h"]
    table = sig.cffi_struct(sig.DAE_TABLE)
    for s in sig.DAE_FUNCTIONS.values():
        assert f"int (*{s.name})({', '.join(a.c() for a in s.args)});" in table


def test_strip_directives_leaves_the_declarations_cffi_takes():
    """cffi's cdef takes no preprocessor directives: strip_directives drops each one (the include
    guard, includes, defines continued over lines, a comment opened on a directive's line) and
    keeps every declaration as it is."""
    from lagcodegen.codegen.cffi_decl import strip_directives
    text = ("/* a header */\n#ifndef X_H\n#define X_H\n\n  #  include \"y.h\" /* the types,\n"
            " * over two lines */\n#define TWO(a) \\\n    ((a) + \\\n     (a))\n"
            "typedef struct x { int n; /* count */ double v[4]; } x;\n"
            "int x_run(const x *s, // the run\n          double t);\n#endif /* X_H */\n")
    out = strip_directives(text)
    assert "#" not in out and "include" not in out and "TWO" not in out and "over two lines" not in out
    assert " ".join(out.split()) == "typedef struct x { int n; double v[4]; } x; int x_run(const x *s, double t);"
    ffi = cffi.FFI()
    with pytest.raises(cffi.CDefError):
        ffi.cdef(text)  # the reason for the helper: cffi refuses the header as it is
    ffi.cdef(out)
    assert [(f, t.type.cname) for f, t in ffi.typeof("x").fields] == [("n", "int"), ("v", "double[4]")]


def test_hand_written_runtime_headers_are_the_cffi_declarations():
    """Each hand-written runtime header is declared once: the modules' cdefs hold its text
    (directives stripped), so a field or prototype changed in the header changes the module's
    declaration, and cffi checks the layout against the compiled header."""
    from lagcodegen.codegen.cffi_decl import header_cdef
    from lagcodegen.simulation.constrained_impacts import _CDEF as impacts_cdef
    from lagcodegen.solvers.cvode.sensitivity import CDEF as sens_cdef
    from lagcodegen.solvers.cvode.sensitivity_stepper import STEPPER_CDEF as sens_stepper_cdef
    from lagcodegen.solvers.cvode.stepper import cvc_stepper_cdef, stepper_cdef
    from lagcodegen.solvers.ida.stepper import stepper_cdef as ida_stepper_cdef
    from lagcodegen.solvers.taylor.stepper import stepper_cdef as taylor_stepper_cdef
    uses = {"lcg_cvsens.h": sens_cdef, "lcg_cvsens_stepper.h": sens_stepper_cdef, "lcg_cvode.h": runtime_cdef(),
            "lcg_cvc.h": runtime_cdef(), "lcg_ida.h": runtime_cdef(), "lcg_taylor.h": taylor_runtime_cdef(),
            "lcg_imp.h": impacts_cdef, "lcg_cvode_stepper.h": stepper_cdef(),
            "lcg_cvc_stepper.h": cvc_stepper_cdef(), "lcg_ida_stepper.h": ida_stepper_cdef(),
            "lcg_taylor_stepper.h": taylor_stepper_cdef()}
    for name, cdef in uses.items():
        decl = header_cdef(name)
        assert decl in cdef, name
        assert "lcg_" in decl and "#" not in decl, name
    # the sensitivity driver's structs: the header's fields, in its order
    ffi = cffi.FFI()
    ffi.cdef(sens_cdef)
    fields = [f for f, _ in ffi.typeof("lcg_cvsens_stats").fields]
    assert fields[:3] == ["nsteps", "nrhs", "nlinsetups"] and fields[-1] == "message"
    assert [f for f, _ in ffi.typeof("lcg_cvsens_events").fields][-1] == "terminated"


def test_stepper_modules_are_keyed_by_the_shared_stepper_header(monkeypatch):
    """Each stepper module's cache key follows the text of lcg_stepper.h (and, on SUNDIALS, of
    lcg_sundials.h): a changed shared header is never served from a stale build."""
    from lagcodegen.solvers.cvode import sensitivity_stepper, stepper as cvode_stepper
    from lagcodegen.solvers.ida import stepper as ida_stepper
    from lagcodegen.solvers.taylor import stepper as taylor_stepper
    seen = {}

    def capture(label, key_texts, *args, **kwargs):
        seen[label] = key_texts
        return label

    builds = [(cvode_stepper, lambda m: m._stepper_runtime.__wrapped__("cvode", "cc", ())),
              (cvode_stepper, lambda m: m._stepper_runtime.__wrapped__("cvc", "cc", ())),
              (ida_stepper, lambda m: m._stepper_runtime.__wrapped__("cc", ())),
              (sensitivity_stepper, lambda m: m._runtime.__wrapped__("cc", ())),
              (taylor_stepper, lambda m: m._stepper_runtime.__wrapped__("cc", ()))]
    for module, build in builds:
        monkeypatch.setattr(module, "driver_runtime", capture)
        build(module)
    assert set(seen) == {"cvode_stepper", "cvc_stepper", "ida_stepper", "cvsens_stepper", "taylor_stepper"}
    shared = "lcg_stepper.h\0" + runtime_package.source("lcg_stepper.h")
    sundials = "lcg_sundials.h\0" + runtime_package.source("lcg_sundials.h")
    for label, texts in seen.items():
        assert shared in texts, label
        assert label == "taylor_stepper" or sundials in texts, label
