"""The variational equations of a scene's Taylor jet: the tangent of the jet program along
each sensitivity direction (forward-mode differentiation of the elementary operations), for
forward sensitivities on the Taylor integrator by jet transport.

For a direction theta (a run-time parameter p_k, or the initial value of a state), the
sensitivity s = dy/d(theta) of the state obeys the tangent of M(q, t) q'' = F(q, q', t) and of
the quadrature rates z' = g (notes eq. 3.16, as on CVODE):

    M s_q'' = dF - (dM) a,    s_z' = dg,    a = q'',

where d is the total derivative along theta (through q, q' by s, through p directly). A model
with generalized speeds, y = (q, v, z) with q' = k(q, v, t) (nq >= nv coordinates: quaternion
joints, Kane's speeds), has the tangent of its kinematics too, s_q' = dk, and M s_v' = dF - (dM) v'
for its speeds. Each
elementary operation u = f(v, w) of the jet (:mod:`.decompose`) gets its tangent
du = f_v dv + f_w dw, itself a Taylor-series operation on jets (a sum of constant multiples of
rows and of products of two rows, and for quotients, logarithms, powers and square roots one
division by the operation's argument or result): so the augmented state (y, s_1 .. s_ns) is
propagated by one Taylor series, with one step size and one order. The mass-matrix solve at
each order reuses M_[0]'s factorization of the states for every direction:

    M_[0] s''_[k] = R_[k] - sum_{j=1..k} M_[j] s''_[k-j],   R = dF - (dM) a.

The tangent operations that involve the accelerations (the products (dM) a) run after the
states' solve at each order; the others before it with the state's operations. The C code, its
build and its runs: :mod:`.sensitivity`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ...errors import ModelError
# ------------------------------------------------------------------------------------------
from .decompose import Const, Decomposition, Op, folded_number


@dataclass
class VariationalDecomposition:
    """The jet program of the states and of their sensitivities along ``ns`` directions.

    Rows: ``0..ny-1`` the state y (q, v, z; q' = v or ``kin``), ``ny (1 + j) .. ny (2 + j) - 1``
    its sensitivity s_j, then
    the accelerations q'' (``acc``), the rows of the states' operations (those of the plain
    decomposition, shifted by ny ns), the accelerations' tangents s_j'' (``sacc[j]``) and the
    tangent operations. ``ops_a``: the states' operations then the tangents that do not involve
    q''; ``ops_b``: those that do (after the states' solve at each order). ``R[j][i]``: the
    right-hand side dF_i - (dM a)_i of direction j; ``dz[j][m]``: the tangent of rate m;
    ``kin``: the coordinates' rates k(q, v, t) of a model with generalized speeds (None: q' = v),
    ``dkin[j][i]`` their tangents along direction j (None without ``kin``);
    ``events[e]``: the row of event function e (a row of the states' operations: no tangent of
    it is needed, the event times' sensitivities come from the event functions' derivatives).
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
    events: list = field(default_factory=list)
    kin: list | None = None
    dkin: list | None = None

    @property
    def n(self) -> int:
        return self.base.n

    @property
    def nq(self) -> int:
        return self.base.nq

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
        number = folded_number(e)
        if number is not None:
            return number
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
    for run-time parameter k, ("state", i) for the initial value of state i (a rotation of a
    quaternion joint: ("state", -1); an initial value enters through s0 alone)."""
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
    kin = None if d.kin is None else [remap_entry(e) for e in d.kin]
    acc = ny + shift
    time_row = None if d.time_row is None else remap(d.time_row)
    # the accelerations' tangents first (rows of their own: the solves write them)
    sacc = []
    for _ in range(ns):
        sacc.append(list(range(tg.nrows, tg.nrows + n)))
        tg.nrows += n
    psyms = {}
    ops_a, ops_b, R, dz, dkin = [], [], [], [], []
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
        if kin is not None:  # generalized speeds: s_q' = dk, the tangent of the kinematics
            dkin.append([_zero(entry_tangent(e)) for e in kin])
        Ts.append((T, entry_tangent))
    for j in range(ns):
        T, entry_tangent = Ts[j]
        tg.phase = ops_b
        R.append([_zero(tg.combo([(1, entry_tangent(F[i]))]
                                 + [(-1, entry_tangent(M[i][m]), acc + m) for m in range(n)]))
                  for i in range(n)])
    ops_a, ops_b = _live(ops_a, ops_b, [e for row in R + dz + dkin for e in row])
    labels = {remap(r): text for r, text in d.labels.items()}
    return VariationalDecomposition(base=d, ns=ns, nrows=tg.nrows, ops_a=base_ops + ops_a, ops_b=ops_b,
                                    consts=tg.consts, M=M, F=F, rates=rates, time_row=time_row, R=R, dz=dz,
                                    sacc=sacc, labels=labels, events=[remap(r) for r in d.events], kin=kin,
                                    dkin=None if kin is None else dkin)


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
