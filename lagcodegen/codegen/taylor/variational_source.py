"""C text of the variational jet of the Taylor integrator: the jet of a scene's states and of
their forward sensitivities along a set of directions (:mod:`.variational`), printed as
``<prefix>_taylor_var.c`` (template taylor/jet_var.c.j2) with its table
``<prefix>_taylor_var_model`` for the Taylor runtime's model-independent driver
(``lcg_taylor_model``: ny (1 + ns) states, nout (1 + ns) outputs: the outputs, then
d out / d theta_j = (d out/dy) s_j + d out/dp).

The text is specific to the set of directions and is generated only when sensitivities are asked
for (:func:`lagcodegen.libraries.taylor_variational_library` compiles it; the runs are
:mod:`lagcodegen.solvers.taylor.sensitivity`): a scene's Taylor code without them is unchanged.
Directions are ``("param", index)`` or ``("state", index)`` (``-1``: a rotation of a quaternion
joint, whose s0 the solver forms per run).
"""

from __future__ import annotations

from dataclasses import dataclass

import symengine as se

from ...errors import ModelError
from ...formulation.kernels import Block, substituter
from ...formulation.scene import Scene
from ...version import __version__
from ..c import c_expr, print_block
from ..record import header_context, new_code
from .decompose import Decomposition, decompose
from .emit import CHUNK, P_MAX, _EventInfo, _jinja
from .schedule import GROUP, item_count, schedule
from .variational import VariationalDecomposition, _is_row, variational


@dataclass(frozen=True)
class _Direction:
    name: str
    base: int        # first row of its sensitivity of y
    sacc: int        # first row of its s''
    R: list
    dz: list
    dkin: list | None = None  # generalized speeds: the tangents of the coordinates' rates


def _outputs_block(scene: Scene, directions: list[tuple[str, int]], ny: int) -> tuple[Block, int]:
    """The outputs and their sensitivities d out/d theta_j = (d out/dy) s_j + d out/dp (theta_j a
    parameter): ``out[k]``, then ``out[nout (1 + j) + k]``."""
    c = substituter(scene)
    outs = [c(se.sympify(o.expr)) for o in scene.output_list()]
    nout = len(outs)
    ys = [se.Symbol(f"y[{i}]") for i in range(ny)]
    targets, exprs = [("out", k) for k in range(nout)], list(outs)
    for j, (kind, index) in enumerate(directions):
        s = [se.Symbol(f"y[{ny * (1 + j) + i}]") for i in range(ny)]
        for k, o in enumerate(outs):
            e = sum((se.diff(o, ys[i]) * s[i] for i in range(ny) if o.has(ys[i])), se.Integer(0))
            if kind == "param":
                e = e + se.diff(o, se.Symbol(f"p[{index}]"))
            if e.atoms(se.Derivative, se.Subs):
                raise ModelError(f"sensitivities of output {scene.output_list()[k].name!r} need derivatives "
                                 "symengine cannot take in closed form")
            targets.append(("out", nout * (1 + j) + k))
            exprs.append(e)
    return Block(targets, exprs), nout * (1 + len(directions))


def _chunks(items: list) -> list[list]:
    """``items`` (operations, :class:`.schedule.Fused` groups) split into runs of at most CHUNK
    operations, each printed as a function of its own."""
    out: list[list] = []
    size = CHUNK
    for item in items:
        if size + item_count(item) > CHUNK:
            out.append([])
            size = 0
        out[-1].append(item)
        size += item_count(item)
    return out


def _sconv_groups(conv_rows: list, ns: int) -> list[list]:
    """The sums sum_{j=1..k} M_[j] s''_[k-j] of every direction and row as loops of up to GROUP
    products: groups of units (direction, row i, its terms [(M row, column)], first
    accumulator)."""
    groups: list[list] = []
    size = GROUP
    for jd in range(ns):
        for i, terms in conv_rows:
            if size + len(terms) > GROUP and size:
                groups.append([])
                size = 0
            groups[-1].append((jd, i, terms, size))
            size += len(terms)
    return groups


def variational_sources(scene: Scene, directions: list[tuple[str, int]], names: list[str],
                        decomposition: Decomposition | None = None,
                        events=()) -> tuple[dict[str, str], VariationalDecomposition]:
    """``{"<prefix>_taylor_var.c": ..., "lcg_taylor_model.h": ...}``: the jet of the states and
    of their sensitivities along ``directions`` (named ``names``) with its table
    ``<prefix>_taylor_var_model``; and the :class:`VariationalDecomposition` it prints. With the
    checked ``events``, the table has their rows (without: the same text as before events
    existed here)."""
    d = decomposition or decompose(scene, events)
    v = variational(d, directions)
    n, ny0, ns = d.n, d.ny, v.ns
    M = v.M
    conv = [(i, M[i][j], j) for i in range(n) for j in range(n) if _is_row(M[i][j])]
    conv_rows = [(i, [(mm, j) for i2, mm, j in conv if i2 == i]) for i in range(n) if any(cc[0] == i for cc in conv)]
    block, nout = _outputs_block(scene, directions, ny0)
    tangent = frozenset(range(ny0, ny0 * (1 + ns))) | frozenset(r for rows in v.sacc for r in rows)
    ops = v.ops_a + v.ops_b
    kinds = {op.kind for op in ops}
    ctx = header_context(scene, new_code(scene))
    # the table's nq counts the speeds and nz the states beyond 2 nv (lcg_taylor_model.h): with
    # generalized speeds the coordinates beyond the speeds count there (as the plain jet's table)
    ctx.update(
        n=n, ny0=ny0, ny=ny0 * (1 + ns), ns=ns, nq=n * (1 + ns), nz=(ny0 - 2 * n) * (1 + ns), nout=nout,
        nrows=v.nrows, kin=v.kin,
        p_max=P_MAX, acc=v.acc, np=len(scene.runtime_parameters), nbase=len(d.ops),
        outputs_block=print_block(block) if nout else "",
        ops_a=v.ops_a, ops_b=v.ops_b,
        chunks=_chunks(v.ops_a[:len(d.ops)]) + _chunks(schedule(v.ops_a[len(d.ops):], tangent)),
        chunks_b=_chunks(schedule(v.ops_b, tangent)),
        sconv_groups=_sconv_groups(conv_rows, ns),
        helpers_inline=-(-len(v.ops_a) // CHUNK) - (-len(v.ops_b) // CHUNK) <= 2,
        kinds=kinds, labels=v.labels, consts=v.consts,
        const_lines=[f"c[{k}] = {c_expr(e)};" for k, e in enumerate(v.consts)],
        M=M, F=v.F, rates=v.rates, conv=conv, conv_rows=conv_rows, time_row=v.time_row,
        mass_constant=d.constant_mass, mass_diagonal=d.diagonal_mass, direction_names=names,
        dirs=[_Direction(names[j], ny0 * (1 + j), v.sacc[j][0], v.R[j], v.dz[j], v.dkin[j] if v.kin is not None
                         else None) for j in range(ns)],
        events=[_EventInfo(ev.name, row, int(ev.direction), int(bool(ev.terminal)))
                for row, ev in zip(v.events, events)])
    env = _jinja()
    header = env.get_template("taylor/lcg_taylor_model.h.j2").render(version=__version__, p_max=P_MAX)
    files = {"lcg_taylor_model.h": header,
             f"{scene.prefix}_taylor_var.c": env.get_template("taylor/jet_var.c.j2").render(**ctx)}
    return files, v
