"""C code generation: a :class:`~lagcodegen.formulation.scene.Scene` rendered through the jinja2 templates.

Expressions are reduced by common-subexpression elimination (symengine's ``cse``, which
matches sympy's) and printed by symengine's C printer (sympy's C99 printer gives the same
text but costs 90% of the generation time of a 20-link pendulum), with every floating-point
constant printed to 17 significant digits. The symbols of the model are renamed
to array elements before elimination: q_i -> y[i], q_i' -> y[n+i], run-time parameter k ->
p[k]; folded parameters become numbers (printed with 17 significant digits, exact doubles).
"""

from __future__ import annotations

import re

import symengine as se

from ..formulation.kernels import Block, model_blocks, sparse_jacobian
from ..formulation.scene import Scene
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
    repl, reduced = se.cse(list(exprs))
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


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    blocks = model_blocks(scene)
    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx)
    code.files[code.source_name] = env.get_template("c/model.c.j2").render(
        **ctx, rhs=print_block(blocks["rhs"]), jac=print_block(blocks.get("jac", Block())),
        out=print_block(blocks["out"]))
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
