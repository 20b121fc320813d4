"""Fortran 2008 code generation: the C backend's functions as a module with C bindings.

:func:`generate_fortran` renders a :class:`~lagcodegen.formulation.scene.Scene` into ``<prefix>.f90``
(module ``<prefix>_mod``) and ``<prefix>.h``, the C backend's header, unchanged. Every
function is ``bind(C, name="<prefix>_...")`` with exactly the C signature, so C programs,
the native CVODE driver and the cffi module of :func:`lagcodegen.build.build` call it exactly like
the C version, and :func:`lagcodegen.build.build` compiles the ``.f90`` with gfortran.

The arithmetic is the C backend's, operation for operation: both print the same operation tree
(:mod:`lagcodegen.codegen.ir`, built once from the same symbol renaming and the same
common-subexpression elimination), :class:`~.fortran_printer.FortranPrinter` as Fortran: ``y[i]`` -> ``y(i+1)``,
``a[i]`` -> ``ydot(N+i+1)``, powers ``a**b`` (gfortran calls the same ``pow``, and turns
``x**2.0d0`` into ``x*x`` as gcc does with ``pow(x, 2)``), every number a double-precision
literal with 17 significant digits (``0.69999999999999996d0``; integers too, so no integer
division can arise), truth values and conditionals as ``merge``, equality tests on reals as
``<=``/``>=`` tests (same result, NaN included), C99 functions without a Fortran intrinsic
(``cbrt``, ``floor``, ...) called from libm through ``bind(C)`` interfaces. The solve of
M q'' = F (Cholesky, LU with partial pivoting as fallback; singular -> 1, non-finite -> 2) and
the Jacobian reusing one factorization are written out in the template as in the C one. With gcc and gfortran at the same optimization
level the results are bit-identical to the C backend's where neither compiler contracts
a*b + c into fused multiply-adds (x86-64 without -march; elsewhere use -ffp-contract=off).

The forms are the C backend's too (:mod:`lagcodegen.codegen.program`): a large right-hand side
in program form (module subroutines of at most CHUNK_STATEMENTS statements, the values in an
allocated array), the tangent Jacobian (its pieces dispatched by ``run_piece`` from the C
backend's tables), a large expanded Jacobian in pieces, and the sparse Jacobian
``<prefix>_jac_sparse`` with ``<prefix>_jac_colptr``/``_rowind`` as ``bind(C)`` variables
behind the C backend's ``<prefix>_sparse.h``.

Constrained systems: :func:`generate_constrained_fortran_source` renders ``<prefix>_dae.f90``
(module ``<prefix>_dae_mod``, templates/fortran/dae.f90.j2), every function of the C
backend's ``<prefix>_dae.c`` (augmented-system solve with its dense LU, index-1 right-hand
side, residuals, projection, outputs, roots, GGL residual and Jacobian) with the C
signatures and return codes, from the expression blocks the C path prints
(:func:`lagcodegen.formulation.constrained.constrained_blocks`) and with the loops of the C
template written out in the same order. Arguments C callers may pass as NULL (``lam``,
``err``) or that may alias (``y`` and ``ynew`` of ``_project``) are ``type(c_ptr)`` values.
:func:`lagcodegen.compile_constrained` (``lang="fortran"``) builds them behind the same
native CVODE and IDA drivers. Systems with contacts: :func:`generate_impact_fortran_source`
renders ``<prefix>_impact.f90`` (module ``<prefix>_impact_mod``, the contact functions of the C
backend's ``<prefix>_impact.c``) and their tables as the C file ``<prefix>_impact_table.c``, for
the same native impact drivers.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from itertools import accumulate

import symengine as se

from ..errors import ModelError
from ..formulation.kernels import Block, cse, model_blocks, require_symmetric, sparse_jacobian
from ..formulation.scene import Scene
from ..formulation.tangent import build_program, tangent_program
from ..version import __version__
from . import ir, lowering, program
from .fortran_printer import INDENT, LIBM_ARITY, LINE, FortranBlock, FortranPrinter, fortran_block, wrap
from .record import GeneratedCode, header_context, new_code
from .templates import environment

#: Longest public Fortran name is <prefix>_err_singular_mass; Fortran names have <= 63 characters.
MAX_PREFIX = 63 - len("_err_singular_mass")


def check_prefix(prefix: str, suffix: str = "_err_singular_mass") -> None:
    """Fortran names start with a letter and have at most 63 characters (``suffix``: the longest
    public name's, after the prefix)."""
    longest = 63 - len(suffix)
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", prefix) or len(prefix) > longest:
        raise ModelError(f"prefix {prefix!r} cannot name a Fortran module: it must start with a letter and have "
                         f"at most {longest} characters (letters, digits, underscores)")


# ----------------------------------------------------------------------------- program form
#: The arrays and scalars the program form's pieces may take, in the order of their arguments
#: (:mod:`lagcodegen.codegen.program`); M is the n x n mass matrix, the others 1-D.
_PIECE_ARGS = ("t", "y", "p", "v", "a", "w", "g", "jz", "s", "x", "M", "G", "Z")
_SHAPES = {"t": "", "M": "(n, n)", "G": "(n, 2 * n)", "Z": "(nz, 2 * n)"}


def _measure() -> program.Measure:
    """The Fortran text sizes the program form's pieces are cut by."""
    printer = FortranPrinter()
    return program.Measure(
        statement=lambda st: len(printer.doprint(st.targets[0])) + 3 + len(printer.doprint(_value(st))),
        value=lambda k, tree: len(str(k)) + 1 + len(printer.doprint(tree)),
        statements=program.CHUNK_STATEMENTS, chars=program.CHUNK_CHARS)


def _value(st: ir.Assign):
    """The value a statement assigns (``target + value`` for an accumulation)."""
    return ir.BinOp("+", st.targets[0], st.value) if st.accumulate else st.value


def _arrays(statements: list) -> tuple[set, set]:
    """(read, written) arrays and scalars of ``statements`` other than their local temporaries."""
    local = {st.targets[0].name for st in statements if st.local}
    read, written = set(), set()
    for st in statements:
        for leaf in ir.walk(_value(st)):
            if isinstance(leaf, ir.Element):
                read.add(leaf.array)
            elif isinstance(leaf, ir.Name) and leaf.name not in local:
                read.add(leaf.name)
        if not st.local:
            written |= {t.array for t in st.targets}
    return read, written


@dataclass
class _Subroutine:
    """A piece of the program form as a module subroutine: its text, its arguments and the libm
    functions it calls."""

    name: str
    args: list
    text: str
    libm: tuple

    def call(self, actual: dict | None = None) -> str:
        """``call name(args)`` with the actual arguments ``actual`` ({dummy: text}, default the same names)."""
        actual = actual or {}
        return f"call {self.name}({', '.join(actual.get(a, a) for a in self.args)})"


def _subroutine(piece: program.Piece, what: str, shapes: dict | None = None) -> _Subroutine:
    """The subroutine of a piece: arguments only those its statements use (no unused dummies),
    arrays assumed-size (M n x n), intent(inout) where written; ``shapes``: other shapes than
    :data:`_SHAPES` (a model with generalized speeds' G and Z)."""
    shapes = {**_SHAPES, **(shapes or {})}
    statements = [ir.Assign(st.targets, _value(st), local=st.local) for st in piece.statements]
    read, written = _arrays(statements)
    args = [a for a in _PIECE_ARGS if a in read | written]
    block = fortran_block(statements, dummies=_PIECE_ARGS, indent=2, what=what)
    lines = [f"  recursive subroutine {piece.name}({', '.join(args)})"]
    for a in args:
        intent = "inout" if a in written else "in"
        shape = shapes.get(a, "(*)")
        lines.append(f"    real(c_double), intent({intent}) :: {a}{shape}")
    if block.decls:
        lines.append(block.decls)
    lines += [block.code, f"  end subroutine {piece.name}"]
    return _Subroutine(piece.name, args, "\n".join(lines), block.libm)


def _int_array(name: str, values: list[int]) -> str:
    """``integer, parameter :: name(k) = [...]`` wrapped in lines of 16 values."""
    values = values or [0]
    rows = [", ".join(str(v) for v in values[k:k + 16]) for k in range(0, len(values), 16)]
    body = ", &\n      ".join(rows)
    return f"  integer, parameter :: {name}({len(values)}) = [ &\n      {body}]"


def _program_context(prog, targets: list, tangent, prefix: str) -> dict:
    """The template context of the program form (templates/fortran/model.f90.j2): the piece
    subroutines, the calls of rhs and jac, the right-hand side's targets, and with ``tangent``
    the tables of the pieces each column runs (``run_piece`` dispatches on a piece's number)."""
    form = program.program_form(prog, targets, tangent, _measure())
    subs = {p.name: _subroutine(p, f"{prefix} program form") for p in form.pieces}
    pad = INDENT * 2
    ctx = dict(nv=form.nv, nw=form.nw, ns=form.ns)
    ctx["rhs_calls"] = "\n".join(pad + subs[p.name].call() for p in form.values + form.mass)
    ctx["jac_calls"] = "\n".join(pad + subs[p.name].call() for p in form.values + form.partials + form.mass)
    targets_block = fortran_block(form.targets, dummies=("t", "y", "p", "v"), what=f"{prefix}_rhs")
    ctx["rhs_targets"] = targets_block.code
    read = set().union(*(subs[p.name].args for p in form.values + form.mass)) | _arrays(form.targets)[0]
    ctx["rhs_unused"] = ", ".join(f"unused_{d} => {d}" if d == "t" else f"unused_{d} => {d}(1:0)"
                                  for d in ("t", "p") if d not in read)
    libm = set(targets_block.libm)
    for sub in subs.values():
        libm |= set(sub.libm)
    ctx["libm"] = libm
    ctx["subroutines"] = "\n\n".join(sub.text for sub in subs.values())
    if tangent is not None:
        cases = []
        used = set()
        for k, piece in enumerate(form.tangent):
            sub = subs[piece.name]
            used |= set(sub.args)
            cases.append(f"    case ({k})\n      {sub.call()}")
        ctx["npieces"] = len(form.tangent)
        ctx["cases"] = "\n".join(cases)
        dispatch = ("t", "y", "p", "v", "a", "w", "g", "jz", "s")
        ctx["run_unused"] = ", ".join(f"unused_{d} => {d}" if d == "t" else f"unused_{d} => {d}(1:0)"
                                      for d in dispatch if d not in used)
        ctx["call_start"] = _int_array("call_start", [0] + list(accumulate(len(c) for c in form.calls)))
        ctx["calls"] = _int_array("calls", [k for c in form.calls for k in c])
        ctx["reset_start"] = _int_array("reset_start", [0] + list(accumulate(len(r) for r in form.resets)))
        ctx["resets"] = _int_array("resets", [x for r in form.resets for x in r])
    ctx["jac_unused"] = ""  # the tangent Jacobian passes every argument to run_piece
    return ctx


def _jacobian_pieces(block: Block, prog: dict, what: str, general: bool = False, nz: int = 0) -> FortranBlock:
    """The expanded Jacobian of a program-form model in pieces (:func:`lagcodegen.codegen.program.block_pieces`:
    subroutines ``jacobian<k>``, the temporaries in an allocated array): the body of ``<prefix>_jac``
    as a :class:`FortranBlock`; the subroutines join the program form's."""
    pieces, array, size = program.block_pieces(block, "x", _measure(), cse)
    # Generalized speeds: G over the (q, v) columns, Z the kinematic rows then the quadratures'.
    shapes = {"G": "(n, nq + n)", "Z": "(nq + nz, nq + n)" if nz else "(nq, nq + n)"} if general else None
    subs = [_subroutine(program.Piece(f"jacobian{k}", "block", statements), f"{what}_jac", shapes)
            for k, statements in enumerate(pieces)]
    prog["subroutines"] += "\n\n" + "\n\n".join(sub.text for sub in subs)
    prog["libm"] = set(prog["libm"]).union(*(sub.libm for sub in subs))
    pad = INDENT * 2
    used = set().union(*(sub.args for sub in subs))
    used |= {"ydot"} if "a" in used else set()  # a = ydot(n+1:2n)
    code = [f"{pad}allocate ({array}({size}), stat=stat)", f"{pad}if (stat /= 0) then",
            f"{pad}  rc = {what}_err_memory", f"{pad}  return", f"{pad}end if"]
    accelerations = "ydot(nq + 1:nq + n)" if general else "ydot(n + 1:2 * n)"  # generalized speeds: a = v'
    code += [pad + sub.call({"a": accelerations}) for sub in subs]
    decls = f"{pad}real(c_double), allocatable :: {array}(:)\n{pad}integer :: stat"
    unused = ", ".join(f"unused_{d} => {d}" if d == "t" else f"unused_{d} => {d}(1:0)"
                       for d in ("t", "y", "ydot", "p") if d not in used)
    return FortranBlock(decls, "\n".join(code), unused, ())


def generate_fortran(scene: Scene) -> GeneratedCode:
    """Render ``<prefix>.f90`` (module ``<prefix>_mod``) and the C header ``<prefix>.h`` of ``scene``.

    The functions are those of :func:`lagcodegen.generate_c` (rhs; jac if the scene asks for
    the Jacobian; outputs if it has any), bound to the same C names and signatures, computed
    from the same expression blocks (:func:`lagcodegen.formulation.kernels.model_blocks`) and
    in the same forms: a large right-hand side in program form (module subroutines of at most
    :data:`~lagcodegen.codegen.program.CHUNK_STATEMENTS` statements,
    :func:`lagcodegen.codegen.program.program_form`), the Jacobian in tangent form when
    ``Scene.jacobian_form`` resolves to "tangent" (:mod:`lagcodegen.formulation.tangent`), else
    expanded (``model_blocks``' symbolic dr/dy).
    """
    check_prefix(scene.prefix)
    require_symmetric(scene.eom, "the Fortran backend")
    n = scene.eom.n
    tangent = program.tangent_jacobian(scene)
    blocks = model_blocks(dataclasses.replace(scene, jacobian=False) if tangent else scene)
    what = scene.prefix
    prog = None
    rhs = None
    if program.use_program(scene, blocks["rhs"]):
        # With generalized speeds the tangent's columns are (q, v): nq + nv of them.
        nv = scene.eom.model.nv if tangent and scene.eom.general else None
        built = build_program(blocks["rhs"], n, nv=nv)
        tp = tangent_program(blocks["rhs"], n, len(scene.eom.quadratures), program=built, nv=nv) if tangent else None
        prog = _program_context(built[0], built[1], tp, what)
    else:
        rhs = print_block(blocks["rhs"], f"{what}_rhs", ("t", "y", "p"), ("t", "p"))
    jac = None
    if scene.jacobian and not tangent and prog:  # a large expanded Jacobian: in pieces too
        jac = _jacobian_pieces(blocks["jac"], prog, what, scene.eom.general, len(scene.eom.quadratures))
    elif scene.jacobian and not tangent:  # accelerations a = q'' (C: a = ydot + N), printed as ydot(N+1:2N)
        jac = print_block(blocks["jac"], f"{what}_jac", ("t", "y", "ydot", "p"), ("t", "y", "ydot", "p"),
                          renames={"a": ("ydot", n)})  # generalized speeds: a = v' = ydot(nq+1:nq+nv), n = nq
    out = print_block(blocks["out"], f"{what}_outputs", ("t", "y", "p"), ("t", "y", "p"))

    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx, program=prog)
    code.jac_pattern = scene.jacobian_pattern()
    sparse = _sparse_context(scene, code, env) if scene.sparse_jacobian else None
    libm = set(out.libm) | set(jac.libm if jac else ()) | set(rhs.libm if rhs else ())
    libm |= set(prog["libm"] if prog else ()) | set(sparse["block"].libm if sparse else ())
    code.files[f"{code.prefix}.f90"] = env.get_template("fortran/model.f90.j2").render(
        **ctx, rhs=rhs, jac=jac, out=out, program=prog, tangent=tangent, sparse=sparse,
        libm=[(name, LIBM_ARITY[name]) for name in sorted(libm)])
    return code


def _sparse_context(scene: Scene, code: GeneratedCode, env) -> dict:
    """The sparse Jacobian ``<prefix>_jac_sparse`` in the module (the kernel of
    :func:`lagcodegen.formulation.kernels.sparse_jacobian`), its structure as the C symbols
    ``<prefix>_jac_colptr``/``_rowind``, and the C backend's header ``<prefix>_sparse.h``."""
    sj = sparse_jacobian(scene, code.jac_pattern)
    n = scene.eom.n
    block = print_block(sj.block, f"{code.prefix}_jac_sparse", ("t", "y", "ydot", "p"), ("t", "y", "ydot", "p"),
                        renames={"a": ("ydot", n)})
    pad = INDENT * 2

    def values(xs):
        xs = list(xs) or [0]
        return ", &\n      ".join(", ".join(str(v) for v in xs[k:k + 16]) for k in range(0, len(xs), 16))
    ctx = dict(nnz=len(sj.entries), colptr=values(sj.colptr), rowind=values(i for i, _ in sj.entries),
               diagonal=sj.diagonal, block=block, nsolve=len(sj.solve_cols), solve_cols=values(sj.solve_cols),
               after="\n".join(f"{pad}vals({k + 1}) = -G({i + 1}, {j + 1})" for k, j, i in sj.copies))
    header = env.get_template("c/jac_sparse.h.j2").render(prefix=code.prefix, PREFIX=code.prefix.upper(),
                                                          version=__version__, model_name=code.model_name,
                                                          nnz=len(sj.entries))
    code.files[f"{code.prefix}_sparse.h"] = header
    code.cffi_headers.append(f"{code.prefix}_sparse.h")
    code.sparse_jacobian = True
    return ctx


# ----------------------------------------------------------------------------- constrained systems
#: Longest public name of the constrained module, after the prefix.
DAE_SUFFIX = "_dae_err_projection"


def print_block(block: Block, what: str, dummies: tuple[str, ...], optional: tuple[str, ...] = (),
                renames: dict | None = None, scalars: tuple[str, ...] = ("t",)) -> FortranBlock:
    """The Fortran statements of a kernel :class:`Block` (:func:`fortran_block`), after the
    common-subexpression elimination the C backend applies to it."""
    try:
        statements = lowering.block_statements(block, se.cse)
    except ModelError as exc:
        raise ModelError(f"{what}: {exc}") from None
    return fortran_block(statements, dummies=dummies, optional=optional, renames=renames, what=what,
                         scalars=scalars)


def generate_constrained_fortran_source(cb, ctx: dict) -> str:
    """``<prefix>_dae.f90`` (module ``<prefix>_dae_mod``): the functions of ``c/dae.c.j2`` for
    the expression blocks ``cb`` (:func:`lagcodegen.formulation.constrained.constrained_blocks`),
    bound to the same C names and signatures and evaluating the same operations.

    ``ctx``: the template context of ``c/dae.h.j2`` (sizes, names, flags).
    """
    prefix = ctx["prefix"]
    check_prefix(prefix, DAE_SUFFIX)
    b = cb.blocks
    plain = ("t", "y", "p")
    blocks = dict(
        mf=print_block(b["mf"], f"{prefix} mass matrix and forces", plain, plain),
        con=print_block(b["con"], f"{prefix} constraints", plain, plain),
        gam=print_block(b["gam"], f"{prefix} gamma", plain, plain),
        out=print_block(b["out"], f"{prefix}_coutputs", (*plain, "lamv"), plain,
                               renames={"lam": ("lamv", 0)}),
        roots=print_block(b["roots"], f"{prefix}_roots", (*plain, "lamv"), plain,
                                 renames={"lam": ("lamv", 0)}),
        ggl_res=print_block(b["ggl_res"], f"{prefix}_ggl_res", ("t", "yy", "yp", "p"),
                                   ("t", "yy", "yp", "p"), renames={"y": ("yy", 0)}),
        ggl_jac=print_block(b["ggl_jac"], f"{prefix}_ggl_jac", ("t", "cj", "yy", "yp", "p"),
                                   ("t", "cj", "yy", "yp", "p"), renames={"y": ("yy", 0)}, scalars=("t", "cj")),
    )
    if ctx.get("general"):  # generalized speeds: the holonomic rows in q, and q' = k(q, v, t)
        blocks.update(conq=print_block(b["conq"], f"{prefix} holonomic rows in q", plain, plain),
                      kin=print_block(b["kin"], f"{prefix} kinematics", plain, plain))
    libm = sorted(set().union(*(blk.libm for blk in blocks.values())))
    text = environment().get_template("fortran/dae.f90.j2").render(
        **ctx, blk=blocks, libm=[(name, LIBM_ARITY[name]) for name in libm])
    return _wrap_long(text)


def _wrap_long(text: str) -> str:
    """``text`` with its code lines longer than LINE (long associate lists of unused arguments)
    wrapped as continuation lines."""
    lines = []
    for line in text.split("\n"):
        stripped = line.lstrip()
        if len(line) > LINE and "!" not in line:
            lines += wrap(stripped, line[:len(line) - len(stripped)])
        else:
            lines.append(line)
    return "\n".join(lines)


def generate_impact_fortran_source(cb, contact: dict, ctx: dict) -> dict[str, str]:
    """``<prefix>_impact.f90`` (module ``<prefix>_impact_mod``, templates/fortran/impact.f90.j2): the
    contact functions of the C backend's ``<prefix>_impact.c`` (gaps, the index-1 right-hand side
    with the active contacts held, the impact, and with friction or GGL the model's numbers at a
    state, ``<prefix>_imp_eval``), bound to the same C names and signatures and evaluating the
    same operations (the solve of the active rows with the LU procedures of the language-neutral
    tree, :mod:`.linalg`); and their tables ``lcg_imp_model`` / ``lcg_imp_friction`` as the C file
    ``<prefix>_impact_table.c`` (templates/c/impact_table.c.j2, the same table text as the C
    backend's file holds), for the model-independent impact drivers.

    ``cb``: the constrained blocks of the system (M and F, and q' = k(q, v, t) with generalized
    speeds, as ``<prefix>_dae.f90`` prints them); ``contact``:
    :func:`lagcodegen.codegen.constrained.contact_context`; ``ctx``: the constrained template context.
    """
    prefix = ctx["prefix"]
    check_prefix(prefix, DAE_SUFFIX)
    plain = ("t", "y", "p")
    blocks = dict(mf=print_block(cb.blocks["mf"], f"{prefix} mass matrix and forces", plain, plain),
                  rows=print_block(contact["rows"], f"{prefix} contact rows", plain, plain))
    if ctx.get("general"):
        blocks["kin"] = print_block(cb.blocks["kin"], f"{prefix} kinematics", plain, plain)
    libm = sorted(set().union(*(blk.libm for blk in blocks.values())))
    values = {k: v for k, v in contact.items() if k != "rows"}
    env = environment()
    text = env.get_template("fortran/impact.f90.j2").render(
        **ctx, **values, blk=blocks, libm=[(name, LIBM_ARITY[name]) for name in libm])
    table = env.get_template("c/impact_table.c.j2").render(**ctx, **values, source=f"{prefix}_impact.f90")
    return {f"{prefix}_impact.f90": _wrap_long(text), f"{prefix}_impact_table.c": table}


class FortranBackend:
    """The Fortran 2008 backend (registered as "fortran" in :mod:`lagcodegen.codegen.languages`):
    prints the operation tree with :class:`FortranPrinter` through templates/fortran/model.f90.j2
    and dae.f90.j2, every function bound to the C backend's name and signature."""

    name = "fortran"
    printer = FortranPrinter
    #: As :class:`lagcodegen.codegen.c.CBackend`'s: the model source is Fortran (no C-only parts).
    suffix, title, link_libs, c_sources = ".f90", "Fortran 2008", ("-lgfortran",), False
    #: The compiler of its sources (compiled apart into objects the C link takes): its name in
    #: messages, the environment variable that names it, the one used otherwise.
    compiler_label, compiler_env, default_compiler = "Fortran compiler", "FC", "gfortran"
    #: As :class:`lagcodegen.codegen.c.CBackend`'s, for the fragments of templates/fortran/bundle/:
    #: the Makefile's compiler variables, CMake's languages (C for the examples), no C properties.
    make_variables = ("FC", "FFLAGS")
    cmake_languages, cmake_library_properties = ("C", "Fortran"), ()

    def module_files(self, stem: str) -> list[str]:
        """The module file ``<stem>_mod.mod`` (lower case, as gfortran writes it) that Fortran
        programs ``use``, installed beside the C header."""
        return [f"{stem.lower()}_mod.mod"]

    def source_description(self, module: str) -> str:
        """What the model source is, for a bundle's README (``module``: the model's prefix)."""
        return f"Fortran 2008 module `{module}_mod`, functions bound to the C names"

    def generate(self, scene: Scene) -> GeneratedCode:
        """The model code of ``scene``: :func:`generate_fortran`."""
        return generate_fortran(scene)

    def check_prefix(self, prefix: str, suffix: str = "_err_singular_mass") -> None:
        """Fortran names start with a letter and have at most 63 characters: :func:`check_prefix`."""
        check_prefix(prefix, suffix)

    def constrained_source(self, cb, ctx: dict) -> dict[str, str]:
        """``<prefix>_dae.f90``: :func:`generate_constrained_fortran_source`."""
        return {f"{ctx['prefix']}_dae.f90": generate_constrained_fortran_source(cb, ctx)}

    def impact_source(self, cb, contact: dict, ctx: dict) -> dict[str, str]:
        """``<prefix>_impact.f90`` with the C tables ``<prefix>_impact_table.c``:
        :func:`generate_impact_fortran_source`."""
        return generate_impact_fortran_source(cb, contact, ctx)
