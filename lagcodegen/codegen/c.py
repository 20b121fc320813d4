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

import symengine as se

from ..formulation.kernels import Block, cse, model_blocks, sparse_jacobian
from ..formulation.scene import Scene
from ..formulation.tangent import NARROW, TangentProgram, tangent_program
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


def _tangent_target(target: tuple, n: int) -> str:
    kind, *idx = target
    if kind == "dM":
        i, k = idx
        return f"dM[{i}][{k}]" if i == k else f"dM[{i}][{k}] = dM[{k}][{i}]"
    if kind == "dF":
        return f"dF[{idx[0]}]"
    return f"jac[j * NY + {2 * n + idx[0]}]"  # ("dZ", k): d z'_k / d y[j]


def print_tangent(prog: TangentProgram) -> dict:
    """The C pieces of the tangent-form Jacobian (:mod:`lagcodegen.formulation.tangent`) for
    templates/c/model.c.j2: ``primal`` (the values v<k> and M), ``partials`` (the constants
    e<m>, after common-subexpression elimination) and per column group its loop ``body``
    (tangent statements, then dM, dF and the quadrature rates' column)."""
    pad = _INDENT
    primal = [f"{pad}const double {v} = {c_expr(e)};" for v, e in prog.primal]
    primal += [f"{pad}{c_target(t)} = {c_expr(e)};" for t, e in prog.values]
    partials = emit_block([f"const double e{t[1]}" for t in prog.partials.targets], prog.partials.exprs)
    groups = []
    for g in prog.groups:
        stored = set(g.stored)

        def line(item, e, depth):
            if not isinstance(item, str):
                return f"{pad * depth}{_tangent_target(item, prog.n)} = {c_expr(e)};"
            return f"{pad * depth}{'' if item in stored else 'const double '}{item} = {c_expr(e)};"

        body = []
        if g.cases:
            body.append(f"{pad * 2}switch (j) {{ /* the statements depending on at most {NARROW} columns */")
            for c, case in g.cases.items():
                body.append(f"{pad * 2}case {c}: {{")
                body += [line(item, e, 3) for item, e in case]
                body += [f"{pad * 3}break;", f"{pad * 2}}}"]
            body.append(f"{pad * 2}}}")
        body += [line(name, e, 2) for name, e in g.statements]
        body += [line(t, e, 2) for t, e in g.targets]
        reset = []
        if g.resets:
            reset.append(f"{pad * 2}switch (j) {{ /* zero again what this column set */")
            for c, items in g.resets.items():
                reset.append(f"{pad * 2}case {c}:")
                reset += [f"{pad * 3}{item if isinstance(item, str) else _tangent_target(item, prog.n)} = 0.0;"
                          for item in items]
                reset.append(f"{pad * 3}break;")
            reset.append(f"{pad * 2}}}")
        groups.append(dict(start=g.start, stop=g.stop, mass=g.mass, force=g.force, body="\n".join(body),
                           reset="\n".join(reset), what="positions" if g.start == 0 else "velocities",
                           stored="".join(f"{pad}double {name} = 0.0;\n" for name in g.stored)))
    seeded = any(str(u).startswith("s[") for g in prog.groups for _, e in g.statements + g.targets
                 for u in e.free_symbols)
    return dict(primal="\n".join(primal), partials=partials, groups=groups, seeded=seeded,
                mass=any(g["mass"] for g in groups), force=any(g["force"] for g in groups))


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    tangent = scene.jacobian and scene.resolved_jacobian_form() == "tangent"
    blocks = model_blocks(dataclasses.replace(scene, jacobian=False) if tangent else scene)
    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    jac = dict(tangent=None)
    if tangent:
        jac = dict(tangent=print_tangent(tangent_program(blocks["rhs"], scene.eom.model.n,
                                                         len(scene.eom.quadratures))))
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx)
    code.files[code.source_name] = env.get_template("c/model.c.j2").render(
        **ctx, rhs=print_block(blocks["rhs"]), jac=print_block(blocks.get("jac", Block())),
        out=print_block(blocks["out"]), **jac)
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
