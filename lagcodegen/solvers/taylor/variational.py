"""The variational equations of a scene's Taylor jet: forward sensitivities on the Taylor
integrator by jet transport (forward-mode differentiation of the jet program).

For a direction theta (a run-time parameter p_k, or the initial value of a state), the
sensitivity s = dy/d(theta) of the state obeys the tangent of M(q, t) q'' = F(q, q', t) and of
the quadrature rates z' = g (notes eq. 3.16, as on CVODE):

    M s_q'' = dF - (dM) a,    s_z' = dg,    a = q'',

where d is the total derivative along theta (through q, q' by s, through p directly). Each
elementary operation u = f(v, w) of the jet (:mod:`.decompose`) gets its tangent
du = f_v dv + f_w dw, itself a Taylor-series operation on jets (a sum of constant multiples of
rows and of products of two rows, and for quotients, logarithms, powers and square roots one
division by the operation's argument or result): so the augmented state (y, s_1 .. s_ns) is
propagated by one Taylor series, with one step size and one order. The mass-matrix solve at
each order reuses M_[0]'s factorization of the states for every direction:

    M_[0] s''_[k] = R_[k] - sum_{j=1..k} M_[j] s''_[k-j],   R = dF - (dM) a.

The tangent operations that involve the accelerations (the products (dM) a) run after the
states' solve at each order; the others before it with the state's operations.

Error control (``errcon``, CVODES's errconS; default on): the sensitivities take part in the
step-size rule with the states' tolerances (w_i = atol_i + rtol |s_i|); off, their weights are
infinite, the steps are those of the states alone and the sensitivities are only as accurate
as those steps make them.

The generated code (``<prefix>_taylor_var.c``, template taylor/jet_var.c.j2) is specific to the
set of directions and is built only when sensitivities are asked for: a scene's Taylor code
without them is unchanged. It presents the augmented system to the model-independent Taylor
driver through the same table (``lcg_taylor_model``: ny (1 + ns) states, nout (1 + ns)
outputs: the outputs, then d out / d theta_j by the output's derivatives), so the run is one
call of ``lcg_taylor_solve``.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass, field
import time

import numpy as np
import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...build import plain_library
from ...codegen.c import c_expr, print_block
from ...codegen.record import header_context, new_code
from ...errors import LagcodegenError, ModelError
from ...formulation.kernels import Block, substituter
from ...formulation.scene import Scene
from ...result import Result
from ...version import __version__
from ..control import CANCELLED, POLL_EVERY, install, raise_pending
# ------------------------------------------------------------------------------------------
from .decompose import Const, Decomposition, Op, decompose
from .emit import CHUNK, P_MAX, _jinja
from .runner import message, taylor_runtime


@dataclass
class VariationalDecomposition:
    """The jet program of the states and of their sensitivities along ``ns`` directions.

    Rows: ``0..ny-1`` the state y, ``ny (1 + j) .. ny (2 + j) - 1`` its sensitivity s_j, then
    the accelerations q'' (``acc``), the rows of the states' operations (those of the plain
    decomposition, shifted by ny ns), the accelerations' tangents s_j'' (``sacc[j]``) and the
    tangent operations. ``ops_a``: the states' operations then the tangents that do not involve
    q''; ``ops_b``: those that do (after the states' solve at each order). ``R[j][i]``: the
    right-hand side dF_i - (dM a)_i of direction j; ``dz[j][m]``: the tangent of rate m.
    Entries are rows, :class:`Const` s or symengine numbers (zero: ``se.Integer(0)``).
    """

    base: Decomposition
    ns: int
    nrows: int
    ops_a: list
    ops_b: list
    consts: list
    M: list
    F: list
    rates: list
    time_row: int | None
    R: list
    dz: list
    sacc: list
    labels: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.base.n

    @property
    def ny(self) -> int:
        return self.base.ny

    @property
    def acc(self) -> int:
        return self.ny * (1 + self.ns)


class _Tangent:
    """Builds the tangent operations (hash-consed, like the states' decomposition)."""

    def __init__(self, d: Decomposition, ns: int):
        self.shift = d.ny * ns
        self.nrows = d.nrows + self.shift
        self.consts = list(d.consts)
        self.const_memo = {e: Const(k) for k, e in enumerate(d.consts)}
        self.memo: dict = {}
        self.phase: list = []

    # -------------------------------------------------------------- constants
    def cval(self, entry):
        """The symengine value of a constant entry."""
        return self.consts[entry.index] if isinstance(entry, Const) else se.sympify(entry)

    def constant(self, e):
        """A constant: a symengine number, or a Const for the run constants (as the states')."""
        e = se.expand(e) if e.free_symbols else e
        if not e.free_symbols:
            if e.is_Number:
                return e
            try:
                value = float(e)
            except (RuntimeError, TypeError, ValueError):
                value = None
            if value is not None:
                return se.Integer(int(value)) if value.is_integer() and abs(value) < 2**53 else se.RealDouble(value)
        if e not in self.const_memo:
            self.const_memo[e] = Const(len(self.consts))
            self.consts.append(e)
        return self.const_memo[e]

    # -------------------------------------------------------------- operations
    def emit(self, kind: str, args=(), coefs=(), const=None, pairs=()) -> int:
        key = (kind, tuple(args), tuple(coefs), const, tuple(pairs))
        if key in self.memo:
            return self.memo[key]
        out = self.nrows
        self.nrows += 1
        self.phase.append(Op(kind, (out,), tuple(args), tuple(coefs), const, None, tuple(pairs)))
        self.memo[key] = out
        return out

    def combo(self, terms):
        """The entry of sum coef * (product of the factors) over ``terms`` (coef, factor, ...):
        factors rows (at most two per term), constant entries or None (zero). None when the sum
        is zero."""
        c0 = se.Integer(0)
        lin: dict[int, object] = {}
        prod: dict[tuple, object] = {}
        for coef, *factors in terms:
            if any(f is None for f in factors):
                continue
            coef = se.sympify(coef)
            rows = []
            for f in factors:
                if isinstance(f, int) and not isinstance(f, bool):
                    rows.append(f)
                else:
                    coef = coef * self.cval(f)
            if coef == 0:
                continue
            if not rows:
                c0 = c0 + coef
            elif len(rows) == 1:
                lin[rows[0]] = lin.get(rows[0], se.Integer(0)) + coef
            else:
                pair = tuple(sorted(rows))
                prod[pair] = prod.get(pair, se.Integer(0)) + coef
        lin = {r: c for r, c in lin.items() if se.expand(c) != 0}
        prod = {pr: c for pr, c in prod.items() if se.expand(c) != 0}
        c0 = se.expand(c0)
        if not lin and not prod:
            return None if c0 == 0 else self.constant(c0)
        if not prod and len(lin) == 1 and c0 == 0:
            (r, c), = lin.items()
            if c == 1:
                return r
        prod = self.factor(prod)
        const = None if c0 == 0 else self.constant(c0)
        items = sorted(lin.items())
        args = [r for r, _ in items]
        coefs = [self.constant(c) for _, c in items]
        if not prod:
            return self.emit("lin", args, coefs, const)
        pairs = [None] * len(args)
        for pr, c in sorted(prod.items()):
            args.append(pr[0])
            coefs.append(self.constant(c))
            pairs.append(pr)
        return self.emit("dot", args, coefs, const, pairs)

    def factor(self, prod: dict) -> dict:
        """Products sharing a row as one product: sum_i c_i x y_i -> x (sum_i c_i y_i), one
        convolution and a linear combination instead of one convolution per product (the
        tangent of c x y along a parameter is c' x y + c x dy + c dx y)."""
        prod = dict(prod)
        while True:
            count: dict[int, int] = {}
            for pair in prod:
                for r in set(pair):
                    count[r] = count.get(r, 0) + 1
            shared = [r for r, m in count.items() if m > 1]
            if not shared:
                return prod
            r = max(shared, key=lambda s: (count[s], -s))
            partners = [(c, pair[1] if pair[0] == r else pair[0]) for pair, c in prod.items() if r in pair]
            prod = {pair: c for pair, c in prod.items() if r not in pair}
            other = self.combo([(c, y) for c, y in partners])
            if other is not None:  # a row: the partners are rows
                pair = tuple(sorted((r, other)))
                prod[pair] = prod.get(pair, se.Integer(0)) + 1

    def quotient(self, num, den: int):
        """The entry of num / den (den a row)."""
        if num is None:
            return None
        if isinstance(num, int) and not isinstance(num, bool):
            return self.emit("div", (num, den))
        return self.emit("cdiv", (den,), const=num)


def _is_row(e) -> bool:
    return isinstance(e, int) and not isinstance(e, bool)


def _tangents(tg: _Tangent, ops: list, T: dict, dconst) -> None:
    """Tangents (into ``T``: row -> entry or None) of the (remapped) operations ``ops`` along one
    direction; ``dconst(c)`` the derivative of a constant entry along it."""
    g = T.get
    half = se.Rational(1, 2)
    for op in ops:
        k, o = op.kind, op.out[0]
        if k == "cst":
            T[o] = dconst(op.const)
        elif k in ("lin", "dot"):
            terms = []
            for i, r in enumerate(op.args):
                c = op.coefs[i]
                pair = op.pairs[i] if op.pairs else None
                if pair is None:
                    terms += [(tg.cval(c), g(r)), (1, dconst(c), r)]
                else:
                    x, y = pair
                    terms += [(tg.cval(c), x, g(y)), (tg.cval(c), g(x), y), (1, dconst(c), x, y)]
            if op.const is not None:
                terms.append((1, dconst(op.const)))
            T[o] = tg.combo(terms)
        elif k == "mul":
            x, y = op.args
            T[o] = tg.combo([(1, x, g(y)), (1, g(x), y)])
        elif k == "sqr":
            x, = op.args
            T[o] = tg.combo([(2, x, g(x))])
        elif k == "div":  # u = x/y: du = (dx - u dy)/y
            x, y = op.args
            T[o] = tg.quotient(tg.combo([(1, g(x)), (-1, o, g(y))]), y)
        elif k == "cdiv":  # u = c/y: du = (dc - u dy)/y
            y, = op.args
            T[o] = tg.quotient(tg.combo([(1, dconst(op.const)), (-1, o, g(y))]), y)
        elif k == "sincos":
            x, = op.args
            s, c = op.out
            T[s] = tg.combo([(1, c, g(x))])
            T[c] = tg.combo([(-1, s, g(x))])
        elif k == "sinhcosh":
            x, = op.args
            s, c = op.out
            T[s] = tg.combo([(1, c, g(x))])
            T[c] = tg.combo([(1, s, g(x))])
        elif k == "exp":
            x, = op.args
            T[o] = tg.combo([(1, o, g(x))])
        elif k == "log":
            x, = op.args
            T[o] = tg.quotient(g(x), x)
        elif k == "sqrt":  # du = dx / (2 u)
            x, = op.args
            T[o] = tg.quotient(tg.combo([(half, g(x))]), o)
        elif k == "pow":  # u = x^a: du = a u dx / x + u log(x) da
            x, = op.args
            a = op.const
            dx = tg.quotient(tg.combo([(tg.cval(a), o, g(x))]), x)
            da = dconst(a)
            if da is not None:
                logx = tg.emit("log", (x,))
                dx = tg.combo([(1, dx), (1, tg.combo([(1, o, logx)]), da)])
            T[o] = dx
        elif k == "tan":  # u = tan x, v = u^2: du = (1 + v) dx, dv = 2 u du
            x, = op.args
            u, v = op.out
            T[u] = tg.combo([(1, g(x)), (1, v, g(x))])
            T[v] = tg.combo([(2, u, T[u])])
        else:  # pragma: no cover - every kind of decompose.Op is handled above
            raise ModelError(f"method='taylor': no tangent of the operation kind {k!r}")


def variational(d: Decomposition, directions: list[tuple[str, int]]) -> VariationalDecomposition:
    """The jet program of ``d``'s states and of their tangents along ``directions``: ("param", k)
    for run-time parameter k, ("state", i) for the initial value of state i."""
    ns, ny, n = len(directions), d.ny, d.n
    shift = ny * ns
    tg = _Tangent(d, ns)

    def remap(r):
        return r if r < ny else r + shift

    def remap_entry(e):
        return remap(e) if _is_row(e) else e

    base_ops = [Op(op.kind, tuple(map(remap, op.out)), tuple(map(remap, op.args)), op.coefs, op.const, op.expr,
                   tuple(None if pr is None else tuple(map(remap, pr)) for pr in op.pairs)) for op in d.ops]
    M = [[remap_entry(e) for e in row] for row in d.M]
    F = [remap_entry(e) for e in d.F]
    rates = [remap_entry(e) for e in d.rates]
    acc = ny + shift
    time_row = None if d.time_row is None else remap(d.time_row)
    # the accelerations' tangents first (rows of their own: the solves write them)
    sacc = []
    for _ in range(ns):
        sacc.append(list(range(tg.nrows, tg.nrows + n)))
        tg.nrows += n
    psyms = {}
    ops_a, ops_b, R, dz = [], [], [], []
    Ts = []
    for j, (kind, index) in enumerate(directions):
        if kind == "param":
            sym = psyms.setdefault(index, se.Symbol(f"p[{index}]"))

            def dconst(c, sym=sym):
                if c is None:
                    return None
                value = se.diff(tg.cval(c), sym)
                return None if value == 0 else tg.constant(value)
        else:
            def dconst(c):
                return None
        T = {r: ny * (1 + j) + r for r in range(ny)}
        tg.phase = ops_a
        _tangents(tg, base_ops, T, dconst)

        def entry_tangent(e, T=T, dconst=dconst):
            return T.get(e) if _is_row(e) else dconst(e)

        dz.append([_zero(entry_tangent(e)) for e in rates])
        Ts.append((T, entry_tangent))
    for j in range(ns):
        T, entry_tangent = Ts[j]
        tg.phase = ops_b
        R.append([_zero(tg.combo([(1, entry_tangent(F[i]))]
                                 + [(-1, entry_tangent(M[i][m]), acc + m) for m in range(n)]))
                  for i in range(n)])
    ops_a, ops_b = _live(ops_a, ops_b, [e for row in R + dz for e in row])
    labels = {remap(r): text for r, text in d.labels.items()}
    return VariationalDecomposition(base=d, ns=ns, nrows=tg.nrows, ops_a=base_ops + ops_a, ops_b=ops_b,
                                    consts=tg.consts, M=M, F=F, rates=rates, time_row=time_row, R=R, dz=dz,
                                    sacc=sacc, labels=labels)


def _live(ops_a: list, ops_b: list, entries: list) -> tuple[list, list]:
    """The tangent operations ``ops_a``, ``ops_b`` without those whose rows nothing uses (the
    right-hand sides and rate tangents ``entries`` need them, or a later operation does): the
    tangent of every operation is built, but the equations need only some (the tangent of a
    product whose factors were folded elsewhere, of an entry of M that only enters through
    (dM) q'')."""
    live = {e for e in entries if _is_row(e)}
    kept = []
    for op in reversed(ops_a + ops_b):
        if any(o in live for o in op.out):
            kept.append(op)
            live.update(op.args)
            live.update(r for pair in op.pairs if pair is not None for r in pair)
    kept = {id(op) for op in kept}
    return [op for op in ops_a if id(op) in kept], [op for op in ops_b if id(op) in kept]


def _zero(e):
    return se.Integer(0) if e is None else e


# ------------------------------------------------------------------ the generated code
@dataclass(frozen=True)
class _Direction:
    name: str
    base: int        # first row of its sensitivity of y
    sacc: int        # first row of its s''
    R: list
    dz: list


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


def variational_sources(scene: Scene, directions: list[tuple[str, int]], names: list[str],
                        decomposition: Decomposition | None = None) -> tuple[dict[str, str], VariationalDecomposition]:
    """``{"<prefix>_taylor_var.c": ..., "lcg_taylor_model.h": ...}``: the jet of the states and
    of their sensitivities along ``directions`` (named ``names``) with its table
    ``<prefix>_taylor_var_model``; and the :class:`VariationalDecomposition` it prints."""
    d = decomposition or decompose(scene)
    v = variational(d, directions)
    n, ny0, ns = d.n, d.ny, v.ns
    M = v.M
    conv = [(i, M[i][j], j) for i in range(n) for j in range(n) if _is_row(M[i][j])]
    conv_rows = [(i, [(mm, j) for i2, mm, j in conv if i2 == i]) for i in range(n) if any(cc[0] == i for cc in conv)]
    block, nout = _outputs_block(scene, directions, ny0)
    ops = v.ops_a + v.ops_b
    kinds = {op.kind for op in ops}
    ctx = header_context(scene, new_code(scene))
    ctx.update(
        n=n, ny0=ny0, ny=ny0 * (1 + ns), ns=ns, nq=n * (1 + ns), nz=d.nz * (1 + ns), nout=nout, nrows=v.nrows,
        p_max=P_MAX, acc=v.acc, np=len(scene.runtime_parameters), nbase=len(d.ops),
        outputs_block=print_block(block) if nout else "",
        ops_a=v.ops_a, ops_b=v.ops_b,
        chunks=[v.ops_a[k:k + CHUNK] for k in range(0, len(v.ops_a), CHUNK)],
        chunks_b=[v.ops_b[k:k + CHUNK] for k in range(0, len(v.ops_b), CHUNK)],
        kinds=kinds, labels=v.labels, consts=v.consts,
        const_lines=[f"c[{k}] = {c_expr(e)};" for k, e in enumerate(v.consts)],
        M=M, F=v.F, rates=v.rates, conv=conv, conv_rows=conv_rows, time_row=v.time_row,
        mass_constant=d.constant_mass, mass_diagonal=d.diagonal_mass, direction_names=names,
        dirs=[_Direction(names[j], ny0 * (1 + j), v.sacc[j][0], v.R[j], v.dz[j]) for j in range(ns)])
    env = _jinja()
    header = env.get_template("taylor/lcg_taylor_model.h.j2").render(version=__version__, p_max=P_MAX)
    files = {"lcg_taylor_model.h": header,
             f"{scene.prefix}_taylor_var.c": env.get_template("taylor/jet_var.c.j2").render(**ctx)}
    return files, v


# ------------------------------------------------------------------ build and run
_STATS = ("nsteps", "njet", "order", "nroot", "t_reached", "h_last", "h_min", "h_max", "model_error")


class VariationalModule:
    """The compiled jet of a scene's states and sensitivities along a set of directions, run by
    the Taylor runtime's driver. Not reentrant (its options struct is reused)."""

    def __init__(self, cm, scene: Scene, names: list[str], directions: list[tuple[str, int]], s0: np.ndarray,
                 cc: str | None = None, verbose: bool = False):
        code = cm.code
        self.names, self.directions, self.s0 = list(names), list(directions), s0
        self.state_names, self.output_names = list(code.state_names), list(code.output_names)
        self.n, self.ny, self.nout, self.ns = code.n, code.ny, code.nout, len(names)
        files, self.decomposition = variational_sources(scene, directions, self.names)
        rt = self.rt = taylor_runtime(cc)
        self.library, self.path, _ = plain_library(f"the Taylor sensitivities of model {code.model_name!r}",
                                                   f"{code.prefix}_taylor_var", files, cc, verbose=verbose)
        getter = getattr(self.library, f"{code.prefix}_taylor_var_table")
        getter.restype = ctypes.c_void_p
        self.table = rt.ffi.cast("const lcg_taylor_model *", getter())
        nyv = self.ny * (1 + self.ns)
        if (self.table.ny, self.table.nout, self.table.nrows) != (nyv, self.nout * (1 + self.ns),
                                                                   self.decomposition.nrows):
            raise LagcodegenError(f"the Taylor sensitivity library of model {code.model_name!r} ({self.path}) has "
                                  "another layout than its code")
        self.opt = rt.ffi.new("lcg_taylor_options *")
        self.opt.poll = install(rt)
        self.opt.poll_every = POLL_EVERY
        self.st = rt.ffi.new("lcg_taylor_stats *")

    def simulate(self, t: np.ndarray, y0: np.ndarray, p: np.ndarray, *, rtol: float, atol, errcon: bool = True,
                 max_step: float = 0.0, max_steps: int = 1_000_000, order: int | None = None,
                 max_wall: float = 0.0) -> Result:
        """The trajectory and its sensitivities at ``t`` from y(t[0]) = ``y0``: a Result whose
        ``sensitivities`` (nt, ns, ny + nout) hold d(state or output)/d(direction)."""
        ffi, lib = self.rt.ffi, self.rt.lib
        ny, ns, nout = self.ny, self.ns, self.nout
        nyv = ny * (1 + ns)
        atol = np.broadcast_to(np.asarray(atol, dtype=float), (ny,))
        atol_all = np.ascontiguousarray(np.concatenate([atol] + [atol if errcon else np.full(ny, np.inf)] * ns))
        y0v = np.ascontiguousarray(np.concatenate([np.asarray(y0, dtype=float), self.s0.ravel()]))
        nt = t.shape[0]
        yout = np.empty((nt, nyv))
        out = np.empty((nt, max(nout * (1 + ns), 1)))
        opt, st, fb = self.opt, self.st, ffi.from_buffer
        opt.rtol = rtol
        opt.atol = float(atol.min())
        opt.atol_vec = fb("double[]", atol_all)
        opt.max_steps = int(max_steps)
        opt.max_step = float(max_step)
        opt.order = int(order or 0)
        opt.max_wall = float(max_wall)
        p = np.ascontiguousarray(p, dtype=float)
        start = time.perf_counter()
        flag = lib.lcg_taylor_solve(self.table, fb("double[]", p) if p.size else ffi.NULL, fb("double[]", y0v), nt,
                                    fb("double[]", np.ascontiguousarray(t)), fb("double[]", yout),
                                    fb("double[]", out), opt, st, ffi.NULL)
        wall = time.perf_counter() - start
        if flag == CANCELLED:
            raise_pending()
        nsteps, njet, order_used, nroot, t_reached, h_last, h_min, h_max, model_error = (getattr(st, k)
                                                                                         for k in _STATS)
        stats = {"steps": nsteps, "rhs_evals": njet, "jet_evals": njet, "order": order_used, "t_reached": t_reached,
                 "h_last": h_last, "h_min": h_min, "h_max": h_max, "model_error": model_error, "wall_time": wall}
        done = min(int(st.nt_done), nt)
        sl = slice(0, done)
        res = Result(t=t[sl].copy(), y=yout[sl, :ny].copy(), state_names=self.state_names,
                     outputs={name: out[sl, i].copy() for i, name in enumerate(self.output_names)}, stats=stats,
                     status=flag, message="success" if flag == 0 else message(
                         flag, st.model_error, ffi.string(st.message).decode(errors="replace")),
                     backend="native", method="taylor", n_coordinates=self.n)
        s = yout[sl, ny:].reshape(done, ns, ny)
        ds = out[sl, nout:nout * (1 + ns)].reshape(done, ns, nout)
        res.set_sensitivities(self.names, self.state_names + self.output_names, np.concatenate([s, ds], axis=2))
        return res


def directions_of(cm, names) -> tuple[list[str], list[tuple[str, int]], np.ndarray]:
    """(names, directions, s0) of the sensitivity directions ``names`` (run-time parameters,
    ``"<q>(0)"``, ``"<q>_dot(0)"``; parsed as on CVODE, the same errors)."""
    from ..cvode.sensitivity import directions
    names, which, s0 = directions(cm, names)
    dirs = [("param", int(k)) if k >= 0 else ("state", int(np.argmax(s0[j]))) for j, k in enumerate(which)]
    return names, dirs, s0


def variational_module(cm, scene: Scene, names) -> VariationalModule:
    """The compiled variational jet of ``cm`` along ``names`` (built once per set of directions,
    then kept with the compiled model)."""
    names, dirs, s0 = directions_of(cm, names)
    key = ("taylor-sensitivities", tuple(names))
    module = cm.solver_state.get(key)
    if module is None:
        module = cm.solver_state[key] = VariationalModule(cm, scene, names, dirs, s0)
    return module
