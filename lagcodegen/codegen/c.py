"""C code generation: a :class:`~lagcodegen.formulation.scene.Scene` rendered through the jinja2 templates.

Expressions are reduced by common-subexpression elimination (symengine's ``cse``, which
matches sympy's) and printed by symengine's C printer (sympy's C99 printer gives the same
text but costs 90% of the generation time of a 20-link pendulum), with every floating-point
constant printed to 17 significant digits. The symbols of the model are renamed
to array elements before elimination: q_i -> y[i], q_i' -> y[n+i], run-time parameter k ->
p[k]; folded parameters become numbers (printed with 17 significant digits, exact doubles).
"""

from __future__ import annotations

import dataclasses
import re
from itertools import accumulate

import symengine as se

from ..formulation.kernels import Block, count_ops, cse, model_blocks, sparse_jacobian
from ..formulation.scene import Scene
from ..formulation.tangent import TangentProgram, build_program, tangent_program
from ..version import __version__
from .record import GeneratedCode, header_context, new_code
from .templates import environment

_INDENT = "    "


_NUMBER = re.compile(r"LCGNUM(\d+)X")


def c_expr(expr) -> str:
    """C99 text of a symengine expression (symengine's C printer, with exact constants).

    symengine prints floating-point numbers with 15 significant digits; every float (and every
    integer too large for a C int literal) is therefore printed by Python's repr, the shortest
    text that reads back as the same double.
    """
    expr = se.sympify(expr)
    numbers = [a for a in expr.atoms(se.RealDouble, se.Integer)
               if isinstance(a, se.RealDouble) or abs(int(a)) > 2**31 - 1]
    if not numbers:
        return se.ccode(expr)
    table = {}
    for k, a in enumerate(numbers):
        value = float(a)
        text = repr(value)
        if not any(ch in text for ch in ".e"):
            text += ".0"
        table[k] = f"({text})" if value < 0 else text
    placeholders = {a: se.Symbol(f"LCGNUM{k}X") for k, a in enumerate(numbers)}
    return _NUMBER.sub(lambda m: table[int(m.group(1))], se.ccode(expr.xreplace(placeholders)))


def emit_block(targets: list[str], exprs: list, indent: int = 1) -> str:
    """C statements assigning ``exprs`` to ``targets`` after common-subexpression elimination."""
    pad = _INDENT * indent
    if not exprs:
        return ""
    repl, reduced = cse(exprs)
    lines = [f"{pad}const double {sym} = {c_expr(e)};" for sym, e in repl]
    lines += [f"{pad}{tgt} = {c_expr(e)};" for tgt, e in zip(targets, reduced)]
    return "\n".join(lines)


def c_target(target: tuple, ng: int = 0) -> str:
    """C lvalue of a kernel target: ("M", i, j) fills both triangles, ("G", i, j) is stored by
    columns (G[j] is the column d r / d y_j, solved in place), ("jac", row, col) is the
    column-major ng x ng matrix ``jac``; anything else indexes its array."""
    kind, *idx = target
    if kind == "M":
        i, j = idx
        return f"M[{i}][{j}]" if i == j else f"M[{i}][{j}] = M[{j}][{i}]"
    if kind == "G":
        i, j = idx
        return f"G[{j}][{i}]"
    if kind == "jac":
        row, col = idx
        return f"jac[{col * ng + row}]"
    return kind + "".join(f"[{k}]" for k in idx)


def print_block(block: Block, ng: int = 0) -> str:
    """The C statements of a kernel :class:`Block` (after common-subexpression elimination)."""
    return emit_block([c_target(tg, ng) for tg in block.targets], block.exprs)


#: The program form's pieces: at most this many statements or characters per C function, so that
#: the compiler's time grows like the code's size (gcc's register allocation and dead-store
#: elimination grow much faster on one long function).
CHUNK_STATEMENTS = 120
CHUNK_CHARS = 8000

#: The right-hand side of a scene without the tangent Jacobian is printed in program form
#: (:func:`lagcodegen.formulation.tangent.build_program`, pieces of at most CHUNK_STATEMENTS)
#: from this many operations (symengine's count_ops) on; smaller ones as one function, as before.
PROGRAM_MIN_OPS = 6000


def _chunks(lines: list[str]) -> list[list[str]]:
    out, cur, size = [], [], 0
    for line in lines:
        if cur and (len(cur) >= CHUNK_STATEMENTS or size + len(line) > CHUNK_CHARS):
            out.append(cur)
            cur, size = [], 0
        cur.append(line)
        size += len(line)
    if cur:
        out.append(cur)
    return out


def _functions(name: str, params: str, unused: list[str], lines: list[str] | None,
               pieces: list[list[str]] | None = None) -> tuple[list[str], list[str]]:
    """Static functions ``name<k>(params)`` holding ``lines`` in pieces (or the given ``pieces``);
    returns (definitions, names)."""
    defs, names = [], []
    casts = " ".join(f"(void){u};" for u in unused)
    for k, chunk in enumerate(_chunks(lines) if pieces is None else pieces):
        fname = f"{name}{k}"
        names.append(fname)
        defs.append(f"static NOINLINE void {fname}({params})\n{{\n{_INDENT}{casts}\n" + "\n".join(chunk) + "\n}")
    return defs, names


_VREF = re.compile(r"v\[(\d+)\]")


def _value_pieces(prog, ranges: list[tuple[int, int]], outside: set) -> list[list[list[str]]]:
    """The statements computing the program's values, per range of ``ranges`` in pieces (lists of
    lines). A value read by one statement only (and not in ``outside``: the values the targets
    and the tangent code read) is written into that statement; a value read only within its
    piece is a local ``u<k>``; the others are stored in ``v``."""
    nv = len(prog)
    consumers: list[list[int]] = [[] for _ in range(nv)]
    for j in range(nv):
        for u in prog.exprs[j].free_symbols:
            k = prog.index(u)
            if k is not None:
                consumers[k].append(j)
    inline = [len(consumers[k]) == 1 and k not in outside for k in range(nv)]
    full: list = [None] * nv
    for k in range(nv):
        e = prog.exprs[k]
        sub = {u: full[i] for u in e.free_symbols if (i := prog.index(u)) is not None and inline[i]}
        full[k] = e.xreplace(sub) if sub else e
    texts = {k: c_expr(full[k]) for k in range(nv) if not inline[k]}
    piece: dict[int, int] = {}
    out, count = [], 0
    for start, stop in ranges:
        chunks = _chunks([f"{k}\0{texts[k]}" for k in range(start, stop) if not inline[k]])
        for chunk in chunks:
            for line in chunk:
                piece[int(line.split("\0", 1)[0])] = count
            count += 1
        out.append(chunks)

    def where(j):  # the statement that computes value j (j itself, or the one it is written into)
        while inline[j]:
            j = consumers[j][0]
        return j
    local = {k for k in piece if k not in outside and all(piece[where(j)] == piece[k] for j in consumers[k])}

    def ref(m):
        return f"u{m.group(1)}" if int(m.group(1)) in local else m.group(0)
    result = []
    for chunks in out:
        pieces = []
        for chunk in chunks:
            lines = []
            for line in chunk:
                k, text = line.split("\0", 1)
                text = _VREF.sub(ref, text)
                lhs = f"const double u{k}" if int(k) in local else f"v[{k}]"
                lines.append(f"{_INDENT}{lhs} = {text};")
            pieces.append(lines)
        result.append(pieces)
    return result


def _piece_functions(name: str, params: str, unused: list[str], pieces: list[list[str]]) -> tuple[list, list]:
    defs, names = [], []
    casts = " ".join(f"(void){u};" for u in unused)
    for k, chunk in enumerate(pieces):
        fname = f"{name}{k}"
        names.append(fname)
        defs.append(f"static NOINLINE void {fname}({params})\n{{\n{_INDENT}{casts}\n" + "\n".join(chunk) + "\n}")
    return defs, names


def _param_names(params: str) -> list[str]:
    """The parameter names of a C parameter list ("double t, double M[][N]" -> t, M)."""
    return [re.search(r"(\w+)\s*(\[[^]]*\])*$", a).group(1) for a in params.split(", ")]


def _rhs_target(target: tuple) -> str:
    kind, *idx = target
    if kind == "ydot":
        return f"ydot[{idx[0]}]"
    return c_target(target)


_LOCAL = re.compile(r"\bd(\d+)\b")


def _scratch(lines: list[str], ops: list) -> list[str]:
    """``lines`` with the local tangents d<k> stored in the scratch array s (so that they cross
    the pieces of a column's code)."""
    slot = {str(k): f"s[{i}]" for i, k in enumerate(k for kind, k, _ in ops if kind == "d")}
    out = []
    for line in lines:
        line = line.replace("const double d", "d", 1) if line.lstrip().startswith("const double d") else line
        out.append(_LOCAL.sub(lambda m: slot[m.group(1)], line))
    return out


_WREF = re.compile(r"w\[(\d+)\]")


def _wide_pieces(ops: list, acc: set, shared: set, nw: int) -> list[list[str]]:
    """The wide operations of a block in pieces. The column code has added the narrow parts of
    the tangents in ``acc`` to w[i]; the tangent of wide value i is assigned to w[nw + i] (or to
    a local ``wl<i>`` if only its own piece reads it, and it is not ``shared`` with other blocks):
    tangent = w[i] (if in acc) + the wide terms."""
    chunks = _chunks([_op_line(op) for op in ops])
    piece, k = {}, 0
    for c, chunk in enumerate(chunks):
        for _ in chunk:
            piece[k] = c
            k += 1
    define = {op[1]: j for j, op in enumerate(ops) if op[0] == "w"}
    readers: dict[int, set] = {}
    for j, op in enumerate(ops):
        for m in _WREF.findall(str(op[2])):
            readers.setdefault(int(m), set()).add(piece[j])
    local = {i for i, j in define.items() if i not in shared and readers.get(i, set()) <= {piece[j]}}

    def value(i):
        return f"wl{i}" if i in local else f"w[{nw + i}]"
    out, k = [], 0
    for chunk in chunks:
        lines = []
        for _ in chunk:
            kind, i, e = ops[k]
            k += 1
            text = _WREF.sub(lambda m: value(int(m.group(1))), c_expr(e))
            if kind == "w":
                lhs = f"const double wl{i}" if i in local else f"w[{nw + i}]"
                text = f"w[{i}] + {text}" if i in acc else text
                lines.append(f"{_INDENT}{lhs} = {text};")
            else:
                lines.append(_op_line((kind, i, se.Symbol("LCGTEXT"))).replace("LCGTEXT", text))
        out.append(lines)
    return out


#: Program-form sources whose pieces hold more than this many characters are cut into groups of
#: about GROUP_CHARS, each between ``#if`` lines, so that the build compiles the file as several
#: objects at once (``-DLCG_PARTS=K -DLCG_PART=k``: group g in object g % K, the rest of the file in
#: object 0; ``lagcodegen.build``). Without those macros the file is one translation unit as before.
SPLIT_MIN_CHARS = 100_000
GROUP_CHARS = 20_000


def _group_pieces(defs: list[str]) -> tuple[str, str, int]:
    """The piece functions ``defs`` (static) as the source's text, in groups between ``#if`` lines
    when they exceed SPLIT_MIN_CHARS (then declared ``PIECE``: static in one translation unit,
    hidden across the objects of a split build): (text, prototypes of a split build, number of
    groups)."""
    total = sum(map(len, defs))
    if total <= SPLIT_MIN_CHARS:
        return "\n\n".join(defs), "", 1
    defs = ["PIECE" + d[len("static"):] if d.startswith("static ") else d for d in defs]
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
    protos = "\n".join(d.split("\n", 1)[0] + ";" for d in defs)
    return text, protos, len(groups)


def _ranges(indices: list[int]) -> list[int]:
    """Sorted ``indices`` as [start, stop) pairs, flattened."""
    out: list[int] = []
    for i in sorted(set(indices)):
        if out and out[-1] == i:
            out[-1] = i + 1
        else:
            out += [i, i + 1]
    return out


def _op_line(op: tuple) -> str:
    kind, k, e = op
    if kind == "d":
        return f"{_INDENT}const double d{k} = {c_expr(e)};"
    if kind == "w":
        return f"{_INDENT}w[{k}] += {c_expr(e)};"
    if kind == "g":
        return f"{_INDENT}g[{k}] += {c_expr(e)};"
    return f"{_INDENT}jz[{k}] = {c_expr(e)};"


def print_program(prog, targets: list, tangent: TangentProgram | None = None) -> dict:
    """The C pieces of the program form (templates/c/model.c.j2): the right-hand side's values
    ``v[k]`` computed by static functions of at most CHUNK_STATEMENTS statements each (shared by
    rhs and jac), and with ``tangent`` the Jacobian's: the values only its partial derivatives
    need, one function per column of dr/dy with its narrow statements, and the wide statements
    of each group (:mod:`lagcodegen.formulation.tangent`)."""
    pad = _INDENT
    n_rhs = prog.n_rhs or len(prog)
    vparams = "double t, const double *y, const double *p, double *v"
    vunused = ["t", "y", "p", "v"]
    ctx = dict(nv=max(1, len(prog)), nw=1, ns=1, groups=[], jac_calls=[])
    outside = {prog.index(a) for _, a in targets} - {None}
    defs = []
    if tangent is not None:
        cparams = ("double t, const double *y, const double *p, const double *v, const double *a, double *w, "
                   "double *g, double *jz, double *s")
        unused = ["t", "y", "p", "v", "a", "w", "g", "jz", "s"]
        nscratch = 1
        pieces: list[str] = []
        ncol = 2 * tangent.n
        calls: list[list[int]] = [[] for _ in range(ncol)]
        resets: list[list[int]] = [[] for _ in range(ncol)]

        def add(more, names, columns):
            defs.extend(more)
            for name in names:
                for c in columns:
                    calls[c].append(len(pieces))
                pieces.append(name)
        for gi, g in enumerate(tangent.groups):
            for c, ops in g.columns.items():
                lines = [_op_line(op) for op in ops]
                if len(_chunks(lines)) > 1:  # the local tangents cross pieces: in the scratch array s
                    lines = _scratch(lines, ops)
                    nscratch = max(nscratch, sum(op[0] == "d" for op in ops))
                add(*_functions(f"column{c}_", cparams, unused, lines), [c])
            acc = {k for ops in g.columns.values() for kind, k, _ in ops if kind == "w"}
            owner: dict[int, int] = {}
            for bi, (_, lo, hi, _) in enumerate(g.blocks):
                owner.update((k, bi) for k in range(lo, hi))
            shared = set()
            for bi, (_, _, _, ops) in enumerate(g.blocks):  # read by another block: kept in w
                shared |= {i for op in ops for m in _WREF.findall(str(op[2])) if owner.get(i := int(m)) != bi}
            for bi, (cols, lo, hi, ops) in enumerate(g.blocks):
                # Wide values with only narrow operands have no operation: their tangent is w[i].
                ops = [("w", i, se.Integer(0)) for i in range(lo, hi)
                       if i in acc and all(op[1] != i for op in ops if op[0] == "w")] + ops
                add(*_functions(f"wide{gi}_{bi}_", cparams, unused, None, _wide_pieces(ops, acc, shared, g.nw)),
                    sorted(cols))
                for c in cols:
                    resets[c] += [g.nw + i for i in range(lo, hi) if i in shared]
            for c, ops in g.columns.items():
                resets[c] += sorted({k for kind, k, _ in ops if kind == "w"})
            ctx["nw"] = max(ctx["nw"], g.nw)
        ctx["pieces"] = _int_rows([]) if not pieces else ",\n".join(f"{pad}{f}" for f in pieces)
        ctx["call_start"] = _int_rows([0] + list(accumulate(len(c) for c in calls)))
        ctx["calls"] = _int_rows([k for c in calls for k in c] or [0])
        ranges = [_ranges(r) for r in resets]
        ctx["reset_start"] = _int_rows([0] + list(accumulate(len(r) for r in ranges)))
        ctx["resets"] = _int_rows([x for r in ranges for x in r] or [0])
        ctx["npieces"] = len(pieces)
        ctx["ns"] = nscratch
        for d in defs:
            outside |= {int(k) for k in _VREF.findall(d)}
        rhs_pieces, extra_pieces = _value_pieces(prog, [(0, n_rhs), (n_rhs, len(prog))], outside)
    else:
        rhs_pieces, extra_pieces = _value_pieces(prog, [(0, n_rhs)], outside)[0], []
    vdefs, rhs_calls = _piece_functions("values", vparams, vunused, rhs_pieces)
    more, extra = _piece_functions("partials", vparams, vunused, extra_pieces)
    defs = vdefs + more + defs
    empty = f"{pad}v[0] = 0.0; /* no values: v is read initialized */"
    ctx["rhs_values"] = "\n".join(f"{pad}{f}(t, y, p, v);" for f in rhs_calls) or empty
    ctx["jac_values"] = "\n".join(f"{pad}{f}(t, y, p, v);" for f in rhs_calls + extra) or empty
    # M in pieces of its own too: hundreds of stores into the caller's M cost gcc seconds there.
    mdefs, mass = _functions("mass", "const double *y, const double *p, const double *v, double M[][N]",
                             ["y", "p", "v", "M"],
                             [f"{pad}{c_target(t)} = {c_expr(a)};" for t, a in targets if t[0] == "M"])
    defs += mdefs
    ctx["mass"] = "\n".join(f"{pad}{f}(y, p, v, M);" for f in mass)
    ctx["rhs_targets"] = "\n".join([ctx["mass"]] + [f"{pad}{_rhs_target(t)} = {c_expr(a)};"
                                                     for t, a in targets if t[0] != "M"])
    ctx["functions"] = defs
    return ctx


#: A block printed by print_block_pieces (the expanded Jacobian of a large model) with more operations
#: than this is hash-consed (lagcodegen.formulation.tangent.build_program) rather than eliminated.
BLOCK_CSE_MAX_OPS = 400_000

_TEMP = re.compile(r"\bx(\d+)\b")


def print_block_pieces(block: Block, name: str, params: str, args: str) -> tuple[list[str], str]:
    """A kernel :class:`Block` as static functions ``name<k>(params)`` of at most CHUNK_STATEMENTS
    statements (after common-subexpression elimination, the temporaries in an array ``x``):
    returns (the definitions, a list; the statements of the caller: allocation, calls
    ``name<k>(args)``, free)."""
    if count_ops(block.exprs) > BLOCK_CSE_MAX_OPS:  # symengine's elimination takes minutes: hash-consing
        prog, targets = build_program(block, 0, cse=False)
        nv = len(prog)
        pieces = _value_pieces(prog, [(0, nv)], {prog.index(a) for _, a in targets} - {None})[0]
        pieces += _chunks([f"{_INDENT}{c_target(t)} = {c_expr(a)};" for t, a in targets])
        params = params.replace("double *x", "double *v")
        defs, names = _functions(name, params, _param_names(params), None, pieces)
        calls = [f"{_INDENT}double *v = (double *)malloc({max(nv, 1)} * sizeof(double));",
                 f"{_INDENT}if (v == NULL)", f"{_INDENT * 2}return LCG_ERR_MEMORY;"]
        vargs = ", ".join("v" if a == "x" else a for a in args.split(", "))
        calls += [f"{_INDENT}{f}({vargs});" for f in names] + [f"{_INDENT}free(v);"]
        return defs, "\n".join(calls)
    repl, reduced = cse(block.exprs)

    def text(e):
        return _TEMP.sub(r"x[\1]", c_expr(e))
    lines = [f"{_INDENT}x[{str(sym)[1:]}] = {text(e)};" for sym, e in repl]
    lines += [f"{_INDENT}{c_target(t)} = {text(e)};" for t, e in zip(block.targets, reduced)]
    defs, names = _functions(name, params, _param_names(params), lines)
    nx = max([int(str(sym)[1:]) + 1 for sym, _ in repl] or [1])
    calls = [f"{_INDENT}double *x = (double *)malloc({nx} * sizeof(double));",
             f"{_INDENT}if (x == NULL)", f"{_INDENT * 2}return LCG_ERR_MEMORY;"]
    calls += [f"{_INDENT}{f}({args});" for f in names] + [f"{_INDENT}free(x);"]
    return defs, "\n".join(calls)


def use_program(scene: Scene, rhs: Block) -> bool:
    """True if the right-hand side is printed in program form: with the tangent Jacobian (they
    share its values), or from PROGRAM_MIN_OPS operations on."""
    if scene.jacobian and scene.resolved_jacobian_form() == "tangent" or rhs.defs:
        return True
    return bool(rhs.exprs) and count_ops(rhs.exprs) >= PROGRAM_MIN_OPS


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    tangent = scene.jacobian and scene.resolved_jacobian_form() == "tangent"
    blocks = model_blocks(dataclasses.replace(scene, jacobian=False) if tangent else scene)
    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    extra = dict(program=None)
    if use_program(scene, blocks["rhs"]):
        n = scene.eom.model.n
        built = build_program(blocks["rhs"], n)
        tp = tangent_program(blocks["rhs"], n, len(scene.eom.quadratures), program=built) if tangent else None
        extra = dict(program=print_program(built[0], built[1], tp))
    jac = print_block(blocks["jac"]) if "jac" in blocks and not extra["program"] else ""
    if "jac" in blocks and extra["program"]:  # a large expanded Jacobian: in pieces too
        nz = len(scene.eom.quadratures)
        params = ("double t, const double *y, const double *p, const double *a, double *x, double M[][N], "
                  "double G[][N]" + (", double Z[][2 * N]" if nz else ""))
        defs, jac = print_block_pieces(blocks["jac"], "jacobian", params, "t, y, p, a, x, M, G" + (", Z" if nz else ""))
        jac = jac.replace("LCG_ERR_MEMORY", f"{code.prefix.upper()}_ERR_MEMORY")
        extra["program"]["functions"] += defs
    if extra["program"]:
        program = extra["program"]
        program["functions"], program["prototypes"], program["groups"] = _group_pieces(program["functions"])
        if program["groups"] > 1:
            code.split[code.source_name] = program["groups"]
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


def generate(scene: Scene) -> GeneratedCode:
    """The language interface of :mod:`lagcodegen.codegen`: :func:`generate_c`."""
    return generate_c(scene)


def check_prefix(prefix: str, suffix: str = "") -> None:
    """Every C identifier prefix is usable in C (Fortran limits the length)."""


def constrained_source(cb, ctx: dict) -> dict[str, str]:
    """``<prefix>_dae.c``: the constrained kernels (:func:`lagcodegen.formulation.constrained.constrained_blocks`)."""
    b = cb.blocks
    text = environment().get_template("c/dae.c.j2").render(
        **ctx, mf=print_block(b["mf"]), con=print_block(b["con"]), gam=print_block(b["gam"]),
        out=print_block(b["out"]), root_block=print_block(b["roots"]), ggl_res=print_block(b["ggl_res"]),
        ggl_jac_block=print_block(b["ggl_jac"], cb.ng))
    return {f"{ctx['prefix']}_dae.c": text}
