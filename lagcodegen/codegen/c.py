"""The C99 backend: a :class:`~lagcodegen.formulation.scene.Scene` rendered through the jinja2 templates.

Expressions are reduced by common-subexpression elimination (symengine's ``cse``, which
matches sympy's), turned into the operation tree (:mod:`.lowering`) and printed by
:class:`CPrinter`: the text symengine's own C printer writes, with every floating-point constant
exact (the shortest text that reads back the same double). The symbols of the model are renamed
to array elements before elimination: q_i -> y[i], q_i' -> y[n+i], run-time parameter k -> p[k];
folded parameters become numbers. Large right-hand sides, the tangent Jacobian and large
expanded Jacobians are printed in pieces (:mod:`.program`); the sparse Jacobian in its own files.
"""

from __future__ import annotations

import dataclasses
from itertools import accumulate

from ..errors import ModelError
from ..formulation.branching import tree_parents
from ..formulation.kernels import Block, count_ops, cse, model_blocks, sparse_jacobian
from ..formulation.scene import Scene
from ..formulation.tangent import TangentProgram, build_program, tangent_program
from ..version import __version__
from . import ir, lowering, program
from .record import GeneratedCode, header_context, new_code
from .templates import environment

_INDENT = "    "


_ATOM, _UNARY, _MUL, _ADD, _REL = 4, 3, 2, 1, 0


def _print_double(value: float) -> str:
    """A double as symengine's C printer writes the numerators and denominators of rationals
    (15 significant digits; ".0" appended to an integral text)."""
    text = f"{value:.15g}"
    if "." not in text and "e" not in text:
        text += "." if len(text) == 15 else ".0"
    return text


class CPrinter(ir.Printer):
    """C99 text of :mod:`lagcodegen.codegen.ir` trees (one ``_print_<Node>`` per node kind).

    The text is the one symengine's C printer writes for the same expression: operands in the
    tree's order, parentheses where C's precedence needs them, and around rationals in products
    and negative literals; every floating-point constant by Python's repr (the shortest text
    that reads back the same double). ``layout``: array name -> function of a target's index
    tuple giving the C subscripts (default ``[i][j]...``).
    """

    #: The tree's function names that C's math library spells differently.
    FUNCTIONS = {"abs": "fabs", "max": "fmax", "min": "fmin", "gamma": "tgamma", "loggamma": "lgamma",
                 "ceiling": "ceil", "truncate": "trunc"}
    #: C99 keywords (no array or variable of the generated code may be named so).
    RESERVED = frozenset((
        "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else", "enum", "extern",
        "float", "for", "goto", "if", "inline", "int", "long", "register", "restrict", "return", "short", "signed",
        "sizeof", "static", "struct", "switch", "typedef", "union", "unsigned", "void", "volatile", "while",
        "_Bool", "_Complex", "_Imaginary"))

    def __init__(self, layout: dict | None = None):
        self.layout = layout or {}

    # -- precedence of a node's text
    def _prec(self, node) -> int:
        if isinstance(node, ir.BinOp):
            return _ADD if node.op in "+-" else _MUL
        if isinstance(node, ir.Ratio):
            return _ADD
        if isinstance(node, ir.Neg) or (isinstance(node, ir.Integer) and node.value < 0):
            return _UNARY
        if isinstance(node, ir.Compare):
            return _REL
        return _ATOM

    def _paren(self, node, below: int) -> str:
        text = self.doprint(node)
        return f"({text})" if self._prec(node) < below else text

    # -- leaves
    def _print_Number(self, node: ir.Number) -> str:
        text = repr(node.value)
        if not any(ch in text for ch in ".e"):
            text += ".0"
        return f"({text})" if node.value < 0 else text

    def _print_Integer(self, node: ir.Integer) -> str:
        return str(node.value)

    def _print_Ratio(self, node: ir.Ratio) -> str:
        return f"{_print_double(node.num)}/{_print_double(node.den)}"

    def _print_Name(self, node: ir.Name) -> str:
        if node.name in self.RESERVED:
            raise ModelError(f"the symbol {node.name!r} is a C keyword; rename it")
        return node.name

    def _print_Element(self, node: ir.Element) -> str:
        index = node.index if isinstance(node.index, tuple) else (node.index,)
        place = self.layout.get(node.array)
        if place is not None:
            return node.array + place(index)
        return node.array + "".join(f"[{k}]" for k in index)

    # -- operations
    def _print_Neg(self, node: ir.Neg) -> str:
        text = self._paren(node.arg, _UNARY)
        return f"-({text})" if text.startswith("-") else "-" + text  # never "--": C's decrement

    def _print_BinOp(self, node: ir.BinOp) -> str:
        level = _ADD if node.op in "+-" else _MUL
        left = self._paren(node.left, level)
        if level == _ADD and isinstance(node.right, ir.Ratio):  # a quotient: no parentheses after + or -
            right = self.doprint(node.right)
        else:
            right = self._paren(node.right, level + 1)
        return f"{left} {node.op} {right}" if level == _ADD else f"{left}{node.op}{right}"

    def _print_Power(self, node: ir.Power) -> str:
        return f"pow({self.doprint(node.base)}, {self.doprint(node.exp)})"

    def _print_Call(self, node: ir.Call) -> str:
        return f"{self.FUNCTIONS.get(node.func, node.func)}({', '.join(self.doprint(a) for a in node.args)})"

    def _print_Compare(self, node: ir.Compare) -> str:
        return f"{self.doprint(node.left)} {node.op} {self.doprint(node.right)}"

    def _print_Logic(self, node: ir.Logic) -> str:
        word = " && " if node.op == "and" else " || "
        return "(" + word.join(f"({self.doprint(a)})" for a in node.args) + ")"

    def _print_Not(self, node: ir.Not) -> str:
        return f"!({self.doprint(node.arg)})"

    def _print_Select(self, node: ir.Select) -> str:
        text = "".join(f"(({self.doprint(c)}) ? (\n   {self.doprint(v)}\n)\n: " for c, v in node.cases)
        return text + f"(\n   {self.doprint(node.default)}\n" + ")" * (len(node.cases) + 1)

    def _print_Sign(self, node: ir.Sign) -> str:
        x = self.doprint(node.arg)
        return f"(({x} == 0.0) ? (0.0) : (({x} < 0.0) ? (-1.0) : (1.0)))"


def c_expr(expr, resolve=None) -> str:
    """C99 text of a symengine expression (:func:`lagcodegen.codegen.lowering.expression` printed by
    :class:`CPrinter`): symengine's C text, with every constant exact."""
    return CPrinter().doprint(lowering.expression(expr, resolve))


def c_statement(printer: CPrinter, st: ir.Assign, pad: str = _INDENT) -> str:
    """One C statement: ``const double x = e;`` (a local), ``t += e;`` (accumulate) or ``t1 = t2 = e;``."""
    value = printer.doprint(st.value)
    if st.local:
        return f"{pad}const double {printer.doprint(st.targets[0])} = {value};"
    if st.accumulate:
        return f"{pad}{printer.doprint(st.targets[0])} += {value};"
    return pad + " = ".join(printer.doprint(t) for t in st.targets) + f" = {value};"


def _layout(ng: int = 0) -> dict:
    """C storage of the kernel targets: ("G", i, j) by columns (G[j] is the column d r / d y_j,
    solved in place), ("jac", row, col) the column-major ng x ng matrix ``jac``."""
    return {"G": lambda idx: f"[{idx[1]}][{idx[0]}]", "jac": lambda idx: f"[{idx[1] * ng + idx[0]}]"}


def print_block(block: Block, ng: int = 0) -> str:
    """The C statements of a kernel :class:`Block` (after common-subexpression elimination)."""
    printer = CPrinter(_layout(ng))
    return "\n".join(c_statement(printer, st) for st in lowering.block_statements(block, cse))


#: The C backend's program-form thresholds (:mod:`lagcodegen.codegen.program`): pieces of at most
#: CHUNK_STATEMENTS statements or CHUNK_CHARS characters; program form from PROGRAM_MIN_OPS operations.
CHUNK_STATEMENTS = program.CHUNK_STATEMENTS
CHUNK_CHARS = program.CHUNK_CHARS
PROGRAM_MIN_OPS = program.PROGRAM_MIN_OPS


def _measure() -> program.Measure:
    """The C text sizes the program form's pieces are cut by (CHUNK_STATEMENTS, CHUNK_CHARS)."""
    printer = CPrinter(_layout())
    return program.Measure(statement=lambda st: len(c_statement(printer, st)),
                           value=lambda k, tree: len(str(k)) + 1 + len(printer.doprint(tree)),
                           statements=CHUNK_STATEMENTS, chars=CHUNK_CHARS)


@dataclasses.dataclass
class CFunction:
    """A C function of the program form: ``void name(params)`` whose body casts every parameter
    to void (some pieces read only a few) and runs ``lines``."""

    name: str
    params: list  # (declaration, name)
    lines: list

    def head(self, storage: str = "static") -> str:
        return f"{storage} NOINLINE void {self.name}({', '.join(d for d, _ in self.params)})"

    def text(self, storage: str = "static") -> str:
        casts = " ".join(f"(void){n};" for _, n in self.params)
        return f"{self.head(storage)}\n{{\n{_INDENT}{casts}\n" + "\n".join(self.lines) + "\n}"


#: The parameters of the program form's pieces by kind (declaration, name).
_PIECE_PARAMS = {
    "values": [("double t", "t"), ("const double *y", "y"), ("const double *p", "p"), ("double *v", "v")],
    "tangent": [("double t", "t"), ("const double *y", "y"), ("const double *p", "p"), ("const double *v", "v"),
                ("const double *a", "a"), ("double *w", "w"), ("double *g", "g"), ("double *jz", "jz"),
                ("double *s", "s")],
    "mass": [("const double *y", "y"), ("const double *p", "p"), ("const double *v", "v"), ("double M[][N]", "M")],
}


def _c_function(piece: program.Piece, printer: CPrinter, params: list | None = None) -> CFunction:
    return CFunction(piece.name, params or _PIECE_PARAMS[piece.kind], [c_statement(printer, st) for st in piece.statements])


#: Program-form sources whose pieces hold more than this many characters are cut into groups of
#: about GROUP_CHARS, each between ``#if`` lines, so that the build compiles the file as several
#: objects at once (``-DLCG_PARTS=K -DLCG_PART=k``: group g in object g % K, the rest of the file in
#: object 0; ``lagcodegen.build``). Without those macros the file is one translation unit as before.
SPLIT_MIN_CHARS = 100_000
GROUP_CHARS = 20_000


def _group_pieces(functions: list[CFunction]) -> tuple[str, str, int]:
    """The piece functions (static) as the source's text, in groups between ``#if`` lines
    when they exceed SPLIT_MIN_CHARS (then declared ``PIECE``: static in one translation unit,
    hidden across the objects of a split build): (text, prototypes of a split build, number of
    groups)."""
    defs = [f.text() for f in functions]
    total = sum(map(len, defs))
    if total <= SPLIT_MIN_CHARS:
        return "\n\n".join(defs), "", 1
    defs = [f.text("PIECE") for f in functions]
    groups: list[list[str]] = [[]]
    size = 0
    for d in defs:
        if groups[-1] and size + len(d) > GROUP_CHARS:
            groups.append([])
            size = 0
        groups[-1].append(d)
        size += len(d)
    text = "\n\n".join(f"#if !defined(LCG_PART) || {g} % LCG_PARTS == LCG_PART\n" + "\n\n".join(ds) + "\n#endif"
                        for g, ds in enumerate(groups))
    protos = "\n".join(f.head("PIECE") + ";" for f in functions)
    return text, protos, len(groups)


def print_program(prog, targets: list, tangent: TangentProgram | None = None) -> dict:
    """The C text of the program form (templates/c/model.c.j2; :func:`lagcodegen.codegen.program.program_form`):
    the right-hand side's values ``v[k]`` computed by static functions of at most
    CHUNK_STATEMENTS statements each (shared by rhs and jac), and with ``tangent`` the Jacobian's
    pieces and the tables of the pieces each column runs and the accumulators it zeroes."""
    pad = _INDENT
    printer = CPrinter(_layout())
    form = program.program_form(prog, targets, tangent, _measure())
    ctx = dict(nv=form.nv, nw=form.nw, ns=form.ns, groups=[], jac_calls=[])
    if tangent is not None:
        names = [p.name for p in form.tangent]
        ctx["pieces"] = _int_rows([]) if not names else ",\n".join(f"{pad}{f}" for f in names)
        ctx["call_start"] = _int_rows([0] + list(accumulate(len(c) for c in form.calls)))
        ctx["calls"] = _int_rows([k for c in form.calls for k in c] or [0])
        ctx["reset_start"] = _int_rows([0] + list(accumulate(len(r) for r in form.resets)))
        ctx["resets"] = _int_rows([x for r in form.resets for x in r] or [0])
        ctx["npieces"] = len(names)
    empty = f"{pad}v[0] = 0.0; /* no values: v is read initialized */"
    ctx["rhs_values"] = "\n".join(f"{pad}{f.name}(t, y, p, v);" for f in form.values) or empty
    ctx["jac_values"] = "\n".join(f"{pad}{f.name}(t, y, p, v);" for f in form.values + form.partials) or empty
    ctx["mass"] = "\n".join(f"{pad}{f.name}(y, p, v, M);" for f in form.mass)
    ctx["rhs_targets"] = "\n".join([ctx["mass"]] + [c_statement(printer, st) for st in form.targets])
    ctx["functions"] = [_c_function(piece, printer) for piece in form.pieces]
    return ctx


#: The C backend's threshold of :func:`lagcodegen.codegen.program.block_pieces` (hash-consing above it).
BLOCK_CSE_MAX_OPS = program.BLOCK_CSE_MAX_OPS


def print_block_pieces(block: Block, name: str, before: list, after: list, scratch: str,
                       error: str) -> tuple[list, str]:
    """A kernel :class:`Block` as static functions ``name<k>(before, double *<array>, after)`` of
    at most CHUNK_STATEMENTS statements (:func:`lagcodegen.codegen.program.block_pieces`: the
    temporaries in the array ``scratch``): returns (the functions; the statements of the caller:
    allocation, calls ``name<k>(...)``, free; ``return error`` when the allocation fails).
    ``before``, ``after``: (declaration, name) of the other parameters."""
    printer = CPrinter(_layout())
    pieces, array, size = program.block_pieces(block, scratch, _measure(), cse, BLOCK_CSE_MAX_OPS)
    params = [*before, (f"double *{array}", array), *after]
    functions = [CFunction(f"{name}{k}", params, [c_statement(printer, st) for st in statements])
                 for k, statements in enumerate(pieces)]
    args = ", ".join(n for _, n in params)
    calls = [f"{_INDENT}double *{array} = (double *)malloc({size} * sizeof(double));",
             f"{_INDENT}if ({array} == NULL)", f"{_INDENT * 2}return {error};"]
    calls += [f"{_INDENT}{f.name}({args});" for f in functions] + [f"{_INDENT}free({array});"]
    return functions, "\n".join(calls)


def print_block_program(block: Block, name: str) -> dict:
    """M and F of a rigid-body tree's constrained code (templates/c/_mass_force.j2) from the
    block of its recorded program (:func:`lagcodegen.formulation.kernels.tree_rhs`, targets
    ("M", i, j), ("F", i)): the program hash-consed and cut into static functions
    ``name<k>(t, y, p, v, M, F)`` (:func:`lagcodegen.codegen.program.block_pieces`), as the
    unconstrained model's right-hand side is. Returns the template's ``functions`` (text),
    ``size`` (of the values array v) and ``calls`` (the caller's statements)."""
    params = [("double t", "t"), ("const double *y", "y"), ("const double *p", "p")]
    after = [("double M[][N]", "M"), ("double F[]", "F")]
    printer = CPrinter(_layout())
    pieces, array, size = program.block_pieces(block, "x", _measure(), cse, BLOCK_CSE_MAX_OPS)
    params = [*params, (f"double *{array}", array), *after]
    functions = [CFunction(f"{name}{k}", params, [c_statement(printer, st) for st in statements])
                 for k, statements in enumerate(pieces)]
    args = ", ".join(n for _, n in params)
    return dict(functions="\n\n".join(f.text() for f in functions), size=size,
                calls="\n".join(f"{_INDENT}{f.name}({args});" for f in functions))


def mass_force_text(cb) -> dict | None:
    """:func:`print_block_program` of the tree program ``cb.blocks["mf_program"]`` of constrained
    blocks ``cb``, printed once per ``cb`` (kept in ``cb.printed``); None for a model without a
    tree, or whose M and F have fewer than PROGRAM_MIN_OPS operations as expressions (a small tree:
    printed from the block ``mf`` as before, so that its C evaluates the same operations as its
    Fortran, :func:`lagcodegen.codegen.fortran.generate_constrained_fortran_source`; a larger
    tree's C and Fortran agree to rounding)."""
    if not cb.blocks.get("mf_program") or count_ops(cb.blocks["mf"].exprs) < PROGRAM_MIN_OPS:
        return None
    if "mf_program" not in cb.printed:
        cb.printed["mf_program"] = print_block_program(cb.blocks["mf_program"], "mass_force")
    return cb.printed["mf_program"]


def use_program(scene: Scene, rhs: Block) -> bool:
    """True if the right-hand side is printed in program form (:func:`lagcodegen.codegen.program.use_program`
    with PROGRAM_MIN_OPS)."""
    return program.use_program(scene, rhs, PROGRAM_MIN_OPS)


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    tangent = program.tangent_jacobian(scene)
    blocks = model_blocks(dataclasses.replace(scene, jacobian=False) if tangent else scene)
    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    extra = dict(program=None, tree_parents=None)
    if use_program(scene, blocks["rhs"]):
        n = scene.eom.model.n
        # With generalized speeds the tangent's columns are (q, v): nq + nv of them.
        nv = scene.eom.model.nv if tangent and scene.eom.general else None
        built = build_program(blocks["rhs"], n, nv=nv)
        tp = tangent_program(blocks["rhs"], n, len(scene.eom.quadratures), program=built, nv=nv) if tangent else None
        extra = dict(program=print_program(built[0], built[1], tp), tree_parents=None)
        if built[0].recorded and not (ctx["diagonal"] or ctx["lu_only"]):  # a rigid-body tree's M
            parents = tree_parents(blocks["rhs"].targets, blocks["rhs"].exprs, scene.eom.model.nv)
            extra["tree_parents"] = None if parents is None else _int_rows(parents)
    jac = print_block(blocks["jac"]) if "jac" in blocks and not extra["program"] else ""
    if "jac" in blocks and extra["program"]:  # a large expanded Jacobian: in pieces too
        nz = len(scene.eom.quadratures)
        rows = "NQ + N" if scene.eom.general else "2 * N"  # Z's columns: d/dy[j] for the state's (q, v)
        params = [("double t", "t"), ("const double *y", "y"), ("const double *p", "p"), ("const double *a", "a"),
                  ("double M[][N]", "M"), ("double G[][N]", "G")] + (
            [(f"double Z[][{rows}]", "Z")] if nz or scene.eom.general else [])
        defs, jac = print_block_pieces(blocks["jac"], "jacobian", params[:4], params[4:], "x",
                                       f"{code.prefix.upper()}_ERR_MEMORY")
        extra["program"]["functions"] += defs
    if extra["program"]:
        form = extra["program"]
        form["functions"], form["prototypes"], form["groups"] = _group_pieces(form["functions"])
        if form["groups"] > 1:
            code.split[code.source_name] = form["groups"]
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx, program=extra["program"])
    code.files[code.source_name] = env.get_template("c/model.c.j2").render(
        **ctx, rhs=None if extra["program"] else print_block(blocks["rhs"]),
        jac=jac, out=print_block(blocks["out"]), tangent=tangent, **extra)
    code.jac_pattern = scene.jacobian_pattern()
    if scene.sparse_jacobian:
        _add_sparse_jacobian(scene, code, env)
    return code


def _int_rows(values: list[int], per_line: int = 16) -> str:
    rows = [", ".join(str(v) for v in values[k:k + per_line]) for k in range(0, len(values), per_line)]
    return ",\n".join(_INDENT + r for r in rows)


def _add_sparse_jacobian(scene: Scene, code: GeneratedCode, env) -> None:
    """Files <prefix>_sparse.h/.c: <prefix>_jac_sparse, the structurally nonzero entries of df/dy
    in compressed-column order (:func:`lagcodegen.formulation.kernels.sparse_jacobian`)."""
    sj = sparse_jacobian(scene, code.jac_pattern)
    after = [f"{_INDENT}vals[{k}] = -G[{j}][{i}];" for k, j, i in sj.copies]
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__, model_name=code.model_name,
               nnz=len(sj.entries), colptr=_int_rows(sj.colptr), rowind=_int_rows([i for i, _ in sj.entries]),
               diagonal=sj.diagonal, block=print_block(sj.block), after="\n".join(after),
               solve_cols=_int_rows(sj.solve_cols), nsolve=len(sj.solve_cols))
    code.files[f"{code.prefix}_sparse.h"] = env.get_template("c/jac_sparse.h.j2").render(**ctx)
    code.files[f"{code.prefix}_sparse.c"] = env.get_template("c/jac_sparse.c.j2").render(**ctx)
    code.cffi_headers.append(f"{code.prefix}_sparse.h")
    code.sparse_jacobian = True


def _constrained_source(cb, ctx: dict) -> dict[str, str]:
    """``<prefix>_dae.c``: the constrained kernels (:func:`lagcodegen.formulation.constrained.constrained_blocks`)."""
    b = cb.blocks
    mfp = mass_force_text(cb)
    text = environment().get_template("c/dae.c.j2").render(
        **ctx, mf_program=mfp, mf="" if mfp else print_block(b["mf"]), con=print_block(b["con"]), gam=print_block(b["gam"]),
        out=print_block(b["out"]), root_block=print_block(b["roots"]), ggl_res=print_block(b["ggl_res"]),
        ggl_jac_block=print_block(b["ggl_jac"], cb.ng))
    return {f"{ctx['prefix']}_dae.c": text}


def _impact_source(cb, contact: dict, ctx: dict) -> dict[str, str]:
    """``<prefix>_impact.c`` (templates/c/impact.c.j2): the contact functions and their tables
    ``lcg_imp_model`` and (with ``contact["friction"]`` or ``contact["numbers"]``)
    ``lcg_imp_friction`` (lagcodegen/runtime/lcg_imp_model.h) for the impact drivers;
    ``contact``: :func:`lagcodegen.codegen.constrained.contact_context`. M and F are those of
    ``cb`` (a tree's program printed once for both files, :func:`mass_force_text`)."""
    mfp = mass_force_text(cb)
    text = environment().get_template("c/impact.c.j2").render(
        **ctx, **{k: v for k, v in contact.items() if k != "rows"}, mf_program=mfp,
        mf="" if mfp else print_block(cb.blocks["mf"]), rows=print_block(contact["rows"]))
    return {f"{ctx['prefix']}_impact.c": text}


class CBackend:
    """The C99 backend (registered as "c" in :mod:`lagcodegen.codegen.languages`): prints the
    operation tree with :class:`CPrinter` through templates/c/model.c.j2, dae.c.j2, jac_sparse.c.j2."""

    name = "c"
    printer = CPrinter
    #: The model source's suffix, the language's name in texts, what a library of it links beside
    #: libm, and whether the model source is C (the C-only parts of a bundle apply: the standalone
    #: integrators, input tables, sensitivity functions, the reference run).
    suffix, title, link_libs, c_sources = ".c", "C99", (), True
    #: As :class:`lagcodegen.codegen.fortran.FortranBackend`'s: C is compiled with the build's cc.
    compiler_label, compiler_env, default_compiler = "C compiler", "CC", "cc"
    #: A bundle's build files (templates/bundle/, with the fragments of templates/c/bundle/): the
    #: variables its Makefile lets one override beside CC and CFLAGS, CMake's project languages and
    #: the library target's properties.
    make_variables: tuple = ()
    cmake_languages, cmake_library_properties = ("C",), ("C_STANDARD 99", "C_STANDARD_REQUIRED ON")

    def module_files(self, stem: str) -> list[str]:
        """Files a bundle's library installs beside its C header (``stem``: the source's stem): none."""
        return []

    def source_description(self, module: str) -> str:
        """What the model source is, for a bundle's README (``module``: the model's prefix)."""
        return "C99 source of the functions (libm only)"

    def generate(self, scene: Scene) -> GeneratedCode:
        """The model code of ``scene``: :func:`generate_c`."""
        return generate_c(scene)

    def check_prefix(self, prefix: str, suffix: str = "") -> None:
        """Every C identifier prefix is usable in C (Fortran limits the length)."""

    def constrained_source(self, cb, ctx: dict) -> dict[str, str]:
        """``<prefix>_dae.c``: the constrained kernels (:func:`lagcodegen.formulation.constrained.constrained_blocks`)."""
        return _constrained_source(cb, ctx)

    def impact_source(self, cb, contact: dict, ctx: dict) -> dict[str, str]:
        """``<prefix>_impact.c``: the contact functions with their tables (:func:`_impact_source`)."""
        return _impact_source(cb, contact, ctx)
