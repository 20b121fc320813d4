"""The equations of a scene as a list of elementary operations for Taylor-series (automatic
differentiation) recurrences: language-neutral, in topological order, shared subexpressions
computed once.

One job: the decomposition, from symengine expressions to operations; its parts (constants,
trig linearization, labels, mass matrix entries) share the one table of operations being built
and its bounds on work (labels and expansions of large expressions), so they stay together.

A Taylor method needs the normalized derivatives x_[k] = x^(k)(t)/k! of every quantity in the
right-hand side. They follow from recurrences on *elementary* operations (sum, product,
quotient, sin/cos as a pair, exp, log, power, tan, ...), so the expressions of
M(q, t) q'' = F(q, q', t), the quadrature rates z' = g(q, q', t) and the event functions are
decomposed into such operations. Each operation writes one or two *rows* of the jet (the
coefficients of one variable at every order); the state (q, q', z), the time t and the
accelerations q'' own the first rows.

Constant subexpressions (numbers and run-time parameters only) are not series: they are
evaluated once per run into ``c[k]`` (:attr:`Decomposition.consts`) and enter the operations
as coefficients, so that ``g/l*sin(q)`` costs one sin/cos recurrence and one scaling.

Two forms of the expressions are decomposed and the cheaper kept (:func:`decompose`): as
derived, and expanded with products of sines and cosines turned into sums (``sin(a)cos(b) ->
(sin(a + b) + sin(a - b))/2``) and terms grouped by their transcendental factor. The second
turns the ``sin(q1)sin(q2) + cos(q1)cos(q2)`` of a derivation into one ``cos(q1 - q2)`` of the
difference variable ``q1 - q2``: one recurrence instead of four.

Expressions a Taylor method cannot expand (``Abs``, ``sign``, ``Piecewise``, ``Max``/``Min``,
``floor``, ``Heaviside``, ...) raise :class:`~lagcodegen.errors.ModelError` naming them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import symengine as se

# --- the rest of lagcodegen: the one place to repoint when modules move -------------------
from ... import progress
from ...errors import ModelError
from ...formulation.kernels import require_symmetric, symbol_map
from ...formulation.scene import Scene
# ------------------------------------------------------------------------------------------

#: Functions that are not analytic everywhere: their Taylor series does not exist at the
#: switching points, and a Taylor step across one is silently wrong.
NON_ANALYTIC = ("Abs", "sign", "Piecewise", "Max", "Min", "floor", "ceiling", "Heaviside", "DiracDelta",
                "Mod", "KroneckerDelta", "frac", "re", "im", "arg", "conjugate")

#: Relative cost per order of each operation kind (a convolution of length k counts 1),
#: used to choose between the forms of the expressions.
COST = {"cst": 0.0, "dot": 0.0, "lin": 0.1, "mul": 1.0, "sqr": 0.5, "div": 1.0, "cdiv": 1.0, "sincos": 2.0,
        "sinhcosh": 2.0, "exp": 1.0, "log": 1.0, "pow": 2.0, "sqrt": 0.5, "tan": 1.0}

#: Integer powers up to this exponent become products (no division by the base); higher ones
#: use the general power recurrence.
MAX_PRODUCT_POWER = 16


@dataclass(frozen=True)
class Const:
    """Reference to the run constant ``c[index]`` (:attr:`Decomposition.consts`)."""

    index: int


@dataclass(frozen=True)
class Op:
    """One elementary operation: writes rows ``out`` from rows ``args``.

    Kinds and their meaning (x, y: rows; c: constant, a symengine number or :class:`Const`):

    ``cst``       out = const (order 0 only)
    ``lin``       out = sum coefs[i] * args[i] + const
    ``mul``       out = x * y                 ``sqr``   out = x^2
    ``div``       out = x / y                 ``cdiv``  out = const / y
    ``sincos``    out = (sin x, cos x)        ``sinhcosh`` out = (sinh x, cosh x)
    ``exp``       out = exp x                 ``log``   out = log x
    ``pow``       out = x^const (const not a small integer or half-integer)
    ``sqrt``      out = sqrt x                ``tan``   out = (tan x, tan^2 x)
    ``dot``       out = sum coefs[i] * t_i + const, t_i = args[i] or, where ``pairs[i]`` is a
                  pair of rows (x, y), the product x * y: a ``lin`` with the products used
                  only there computed in its own loop (:func:`fuse_products`)
    """

    kind: str
    out: tuple
    args: tuple = ()
    coefs: tuple = ()
    const: object = None
    expr: object = None
    pairs: tuple = ()


@dataclass
class Decomposition:
    """The elementary operations of a scene's equations.

    Rows: ``0..n-1`` q, ``n..2n-1`` q', ``2n..2n+nz-1`` z (the state y), then the
    accelerations q'' (``acc_rows``), the time (``time_row``, or None when t does not occur)
    and the rows of the operations. ``M[i][j]``, ``F[i]``, ``rates[k]``, ``events[e]``: a row,
    a :class:`Const`, or a symengine number (zero entries of M are ``se.Integer(0)``).
    """

    n: int  # the speeds (the size of M): the coordinates unless ``kin``
    nz: int
    nrows: int
    ops: list
    consts: list  # symengine expressions in p[k] and numbers, in evaluation order
    M: list
    F: list
    rates: list
    events: list
    time_row: int | None
    form: str  # "derived" or "trig-linearized"
    cost: float
    labels: dict = field(default_factory=dict)  # row -> short text of the expression
    # Generalized speeds: the coordinates' rates q' = k(q, v, t), an entry per coordinate (rows
    # 0..nq-1 q, nq..nq+n-1 v); None: q' = v (nq = n).
    kin: list | None = None

    @property
    def nq(self) -> int:
        return self.n if self.kin is None else len(self.kin)

    @property
    def ny(self) -> int:
        return self.nq + self.n + self.nz

    @property
    def acc_rows(self) -> list[int]:
        return list(range(self.ny, self.ny + self.n))

    @property
    def constant_mass(self) -> bool:
        """Every entry of M is a constant: M is factored once per run."""
        return all(not isinstance(e, int) for row in self.M for e in row)

    @property
    def diagonal_mass(self) -> bool:
        n = self.n
        return all(_is_zero(self.M[i][j]) for i in range(n) for j in range(n) if i != j)


def _is_zero(entry) -> bool:
    return not isinstance(entry, (int, Const)) and entry == 0


#: An expression printed whole into a label or a message has at most this many nodes as a tree
#: (shared subexpressions counted each time they occur, as the printer writes them); a larger
#: one is described by its head (:func:`_sketch`). Printing a tree costs its size, which for
#: the shared subexpressions of a rigid-body chain grows exponentially with the joints.
LABEL_NODES = 400


def _tree_size(expr, cap: int) -> int:
    """Nodes of ``expr`` as a tree, or ``cap + 1`` if more: at most ``cap`` nodes visited (no
    memo: looking an expression up compares equal ones node by node, as a tree)."""
    count, stack = 0, [expr]
    while stack:
        count += 1
        if count > cap:
            return cap + 1
        stack.extend(stack.pop().args)
    return count


def _sketch(expr) -> str:
    """A few words on a large expression, from its head and its number of operands."""
    args = expr.args
    if isinstance(expr, se.Add):
        return f"sum of {len(args)} terms"
    if isinstance(expr, se.Mul):
        return f"product of {len(args)} factors"
    if isinstance(expr, se.Pow):
        exponent = args[1]
        return f"power {exponent}" if exponent.is_Number else "power"
    return f"{type(expr).__name__}(...)"


def _short(expr, width: int = 60) -> str:
    """``expr`` as text of at most ``width`` characters, for a label or a message: printed
    (and cut) up to :data:`LABEL_NODES` nodes, else :func:`_sketch` (bounded work either way)."""
    text = str(expr) if _tree_size(expr, LABEL_NODES) <= LABEL_NODES else _sketch(expr)
    text = text.replace("*/", "* /")
    return text if len(text) <= width else text[: width - 3] + "..."


def _refuse(expr, where: str, names: dict):
    name = type(expr).__name__
    expr = expr.xreplace(names)
    if name in NON_ANALYTIC:
        raise ModelError(f"method='taylor' cannot integrate {where}: it contains {_short(expr, 120)}, which "
                         f"is not analytic ({name} has no Taylor series at its switching points); use "
                         "an adaptive method (adams/bdf) or events at the switching points")
    raise ModelError(f"method='taylor' cannot integrate {where}: {_short(expr, 120)} has no Taylor "
                     f"recurrence here ({name} is not among +, -, *, /, powers, sin, cos, tan, exp, log, "
                     "sinh, cosh)")


def folded_number(e):
    """``e`` as a symengine number if it is one (exactly, or a float of a closed form such as
    sqrt(2)): an Integer for integral values below 2^53, else a RealDouble; None if it holds
    symbols or does not evaluate."""
    if e.free_symbols:
        return None
    if e.is_Number:
        return e
    try:
        value = float(e)
    except (RuntimeError, TypeError, ValueError):
        return None
    return se.Integer(int(value)) if value.is_integer() and abs(value) < 2**53 else se.RealDouble(value)


class _Decomposer:
    """Hash-consed decomposition: every distinct subexpression becomes one row."""

    def __init__(self, state: dict, time_symbol, n: int, nz: int, nq: int | None = None):
        self.state = state  # symbol -> row
        self.time_symbol = time_symbol
        self.varsyms = set(state) | {time_symbol}
        self.nrows = (n if nq is None else nq) + 2 * n + nz  # y rows then the accelerations
        self.time_row = None
        self.ops: list[Op] = []
        self.consts: list = []
        self.const_memo: dict = {}
        self.memo: dict = {}
        self.op_memo: dict = {}
        self.labels: dict = {}
        self.const_known: dict = {}  # expression -> is_const
        self.where = ""
        self.names: dict = {}  # array symbols -> model symbols, for messages

    # -------------------------------------------------------------- rows and constants
    def is_const(self, e) -> bool:
        """No state variable or time in ``e`` (remembered: the free symbols of a large shared
        expression cost its size as a tree, and each subexpression is asked about several times)."""
        known = self.const_known.get(e)
        if known is None:
            known = self.const_known[e] = not (e.free_symbols & self.varsyms)
        return known

    def constant(self, e):
        """A constant subexpression: a symengine number, or a Const for the run constants."""
        number = folded_number(e)
        return self._const_entry(e) if number is None else number

    def _const_entry(self, e):
        if e not in self.const_memo:
            self.const_memo[e] = Const(len(self.consts))
            self.consts.append(e)
        return self.const_memo[e]

    def emit(self, kind: str, args=(), coefs=(), const=None, expr=None, nout: int = 1):
        key = (kind, tuple(args), tuple(coefs), const)
        if key in self.op_memo:
            out = self.op_memo[key]
        else:
            out = tuple(range(self.nrows, self.nrows + nout))
            self.nrows += nout
            self.ops.append(Op(kind, out, tuple(args), tuple(coefs), const, expr))
            self.op_memo[key] = out
            if expr is not None:
                self.labels[out[0]] = _short(expr)
        return out if nout > 1 else out[0]

    def row(self, e) -> int:
        """A row holding e (a constant gets a ``cst`` row)."""
        node = self.node(e)
        if isinstance(node, int):
            return node
        return self.emit("cst", const=node, expr=e)

    # -------------------------------------------------------------- decomposition
    def node(self, e):
        """Row (int), Const or number standing for e."""
        if e in self.memo:
            return self.memo[e]
        if self.is_const(e):
            result = self.constant(e)
        elif isinstance(e, se.Symbol):
            if e == self.time_symbol:
                if self.time_row is None:
                    self.time_row = self.nrows
                    self.nrows += 1
                    self.labels[self.time_row] = "t"
                result = self.time_row
            else:
                result = self.state[e]
        elif isinstance(e, se.Add):
            result = self.add(e)
        elif isinstance(e, se.Mul):
            result = self.mul(e)
        elif isinstance(e, se.Pow):
            result = self.power(e)
        elif isinstance(e, (se.sin, se.cos)):
            s, c = self.emit("sincos", (self.row(e.args[0]),), expr=se.sin(e.args[0]), nout=2)
            self.memo[se.sin(e.args[0])], self.memo[se.cos(e.args[0])] = s, c
            result = s if isinstance(e, se.sin) else c
        elif isinstance(e, (se.sinh, se.cosh)):
            s, c = self.emit("sinhcosh", (self.row(e.args[0]),), expr=se.sinh(e.args[0]), nout=2)
            self.memo[se.sinh(e.args[0])], self.memo[se.cosh(e.args[0])] = s, c
            result = s if isinstance(e, se.sinh) else c
        elif isinstance(e, se.tan):
            result = self.emit("tan", (self.row(e.args[0]),), expr=e, nout=2)[0]
        elif isinstance(e, se.log) and len(e.args) == 1:
            result = self.emit("log", (self.row(e.args[0]),), expr=e)
        else:
            _refuse(e, self.where, self.names)
        self.memo[e] = result
        return result

    def linear(self, terms: list, c0, expr):
        """Row of sum coef*row + c0 (terms: (coef, row), rows merged)."""
        merged: dict[int, object] = {}
        for coef, r in terms:
            merged[r] = merged.get(r, se.Integer(0)) + coef
        items = [(coef, r) for r, coef in merged.items() if coef != 0]
        if not items:
            return self.constant(c0)
        if len(items) == 1 and items[0][0] == 1 and c0 == 0:
            return items[0][1]
        items.sort(key=lambda it: it[1])
        coefs = tuple(self.constant(c) for c, _ in items)
        const = None if c0 == 0 else self.constant(c0)
        return self.emit("lin", [r for _, r in items], coefs, const, expr=expr)

    def add(self, e):
        c0 = se.Integer(0)
        terms = []
        for term in e.args:
            if self.is_const(term):
                c0 += term
                continue
            coef, rest = self.split_coefficient(term)
            terms.append((coef, self.row(rest)))
        return self.linear(terms, c0, e)

    def split_coefficient(self, term):
        """(constant factor, variable factor) of a product."""
        if isinstance(term, se.Mul):
            cs = [f for f in term.args if self.is_const(f)]
            if cs:
                vs = [f for f in term.args if not self.is_const(f)]
                return se.Mul(*cs), se.Mul(*vs)
        return se.Integer(1), term

    def mul(self, e):
        coef, rest = self.split_coefficient(e)
        factors = rest.args if isinstance(rest, se.Mul) else (rest,)
        num, den = [], []
        for f in factors:
            if isinstance(f, se.Pow) and f.args[1].is_Number and f.args[1] < 0 and f.args[0] != se.E:
                den.append(f.args[0] ** (-f.args[1]))
            else:
                num.append(f)
        if den:
            d = self.product([self.row(f) for f in den])
            if num:
                r = self.emit("div", (self.product([self.row(f) for f in num]), d), expr=e)
            else:
                r = self.emit("cdiv", (d,), const=self.constant(coef), expr=e)
                coef = se.Integer(1)
        else:
            r = self.product([self.row(f) for f in num])
        if coef == 1:
            return r
        return self.linear([(coef, r)], se.Integer(0), e)

    def product(self, rows: list[int]) -> int:
        rows = sorted(rows)
        acc = rows[0]
        for r in rows[1:]:
            acc = self.emit("sqr", (acc,)) if r == acc else self.emit("mul", (acc, r))
        return acc

    def integer_power(self, base, k: int) -> int:
        b = self.row(base)
        if k == 1:
            return b
        if k > MAX_PRODUCT_POWER:
            return self.emit("pow", (b,), const=se.Integer(k), expr=base**k)
        half = self.integer_power(base, k // 2)
        sq = self.emit("sqr", (half,), expr=base ** (2 * (k // 2)))
        return sq if k % 2 == 0 else self.emit("mul", (sq, b), expr=base**k)

    def power(self, e):
        base, ex = e.args
        if base == se.E:
            return self.emit("exp", (self.row(ex),), expr=e)
        if not self.is_const(ex):  # b^x = exp(x log b)
            return self.node(se.exp(ex * se.log(base)))
        if ex.is_Number and isinstance(ex, (se.Integer, se.Rational)):
            two = 2 * ex
            if isinstance(ex, se.Integer) or (isinstance(two, se.Integer) and abs(int(two)) <= 2 * MAX_PRODUCT_POWER):
                m = int(two)  # e = m/2
                r = self.half_power(base, abs(m))
                if m < 0:
                    return self.emit("cdiv", (r,), const=se.Integer(1), expr=e)
                return r
        return self.emit("pow", (self.row(base),), const=self.constant(ex), expr=e)

    def half_power(self, base, m: int) -> int:
        """Row of base^(m/2), m > 0, by products and one square root."""
        if m % 2 == 0:
            return self.integer_power(base, m // 2)
        root = self.emit("sqrt", (self.row(base),), expr=se.sqrt(base))
        if m == 1:
            return root
        return self.emit("mul", (self.integer_power(base, m // 2), root), expr=base ** se.Rational(m, 2))


# ------------------------------------------------------------------ trigonometric linearization
def _product_to_sum(k1: str, a, k2: str, b) -> list:
    """sin/cos(a) * sin/cos(b) as [(coefficient, kind, argument)]."""
    half = se.Rational(1, 2)
    if k1 == "sin" and k2 == "sin":
        return [(half, "cos", a - b), (-half, "cos", a + b)]
    if k1 == "cos" and k2 == "cos":
        return [(half, "cos", a - b), (half, "cos", a + b)]
    if k1 == "sin":  # sin a cos b
        return [(half, "sin", a + b), (half, "sin", a - b)]
    return [(half, "sin", a + b), (-half, "sin", a - b)]  # cos a sin b


def _trig(kind: str, arg):
    return se.sin(arg) if kind == "sin" else se.cos(arg)


#: Powers of a sine or cosine up to this exponent are linearized as products of their factors
#: (``sin(x)**2 -> (1 - cos(2 x))/2``, so that ``sin(x)**2 + cos(x)**2`` cancels to 1).
MAX_TRIG_POWER = 4


def _trig_powers_expanded(factors) -> list:
    """``factors`` with each sin/cos to a small positive integer power as that many factors."""
    out = []
    for f in factors:
        if (isinstance(f, se.Pow) and isinstance(f.args[0], (se.sin, se.cos)) and isinstance(f.args[1], se.Integer)
                and 1 < int(f.args[1]) <= MAX_TRIG_POWER):
            out += [f.args[0]] * int(f.args[1])
        else:
            out.append(f)
    return out


#: An expression whose expansion has more terms than this is not linearized (returned as given):
#: the rigid-body closed forms' forces (thousands of terms, products of up to 14 sines and
#: cosines: 2^13 sums each) would take minutes, and the derived form is the cheaper there anyway.
MAX_LINEARIZED_TERMS = 2000

#: An expression whose expansion may have more terms than this before like terms are combined
#: (:func:`expansion_bound`) is not even expanded (returned as given): expanding the forces of
#: an 8-joint chain (2.4 million products, 130 000 terms) took 27 s, only for the result to be
#: dropped above :data:`MAX_LINEARIZED_TERMS`.
MAX_EXPANSION_BOUND = 25 * MAX_LINEARIZED_TERMS

#: A term with more sine and cosine factors than this keeps them as a product (k factors become
#: 2^(k-1) sines and cosines of sums).
MAX_TRIG_FACTORS = 6


def expansion_bound(expr, *, cap: int = MAX_EXPANSION_BOUND) -> int:
    """An upper bound of the number of terms of ``se.expand(expr)`` (sums, products and integer
    powers multiplied out, like terms not combined), or ``cap + 1`` if above ``cap``. The walk
    stops there: a sum's bound is at least its terms', a product's (of factors with 2 or more
    terms) at least their sum, so it visits about ``cap`` nodes at most."""
    def expands(e) -> bool:
        return isinstance(e, (se.Add, se.Mul)) or (isinstance(e, se.Pow) and isinstance(e.args[1], se.Integer)
                                                   and e.args[1] > 1)

    def combine(e, value: int, child: int) -> int:
        if isinstance(e, se.Add):
            return value + child
        if isinstance(e, se.Mul):
            return value * child
        k = int(e.args[1])
        return child if child == 1 else child ** k if k * child.bit_length() <= cap.bit_length() + 1 else cap + 1

    if not expands(expr):
        return 1
    # frames: [expression, its arguments, next argument, value so far]
    stack = [[expr, expr.args[:1] if isinstance(expr, se.Pow) else expr.args, 0,
              0 if isinstance(expr, se.Add) else 1]]
    while True:
        frame = stack[-1]
        e, args, i, value = frame
        if i < len(args) and value <= cap:
            frame[2] += 1
            a = args[i]
            if expands(a):
                stack.append([a, a.args[:1] if isinstance(a, se.Pow) else a.args, 0, 0 if isinstance(a, se.Add) else 1])
            else:
                frame[3] = combine(e, value, 1)
            continue
        stack.pop()
        value = min(value, cap + 1)
        if not stack:
            return value
        parent = stack[-1]
        parent[3] = combine(parent[0], parent[3], value)


def linearize_trig(expr):
    """Expand ``expr`` and turn every product of sines and cosines (small integer powers
    included) into a sum of sines and cosines of sums and differences of their arguments
    (``expr`` as given when its expansion may exceed :data:`MAX_EXPANSION_BOUND` terms or has
    more than :data:`MAX_LINEARIZED_TERMS`; products of more than :data:`MAX_TRIG_FACTORS`
    factors kept)."""
    if expansion_bound(expr) > MAX_EXPANSION_BOUND:
        return expr
    e = se.expand(expr)
    terms = e.args if isinstance(e, se.Add) else (e,)
    if len(terms) > MAX_LINEARIZED_TERMS:
        return expr
    out = []
    for term in terms:
        factors = _trig_powers_expanded(term.args if isinstance(term, se.Mul) else (term,))
        trig = [f for f in factors if isinstance(f, (se.sin, se.cos))]
        if len(trig) < 2 or len(trig) > MAX_TRIG_FACTORS:
            out.append(term)
            continue
        rest = [f for f in factors if not isinstance(f, (se.sin, se.cos))]
        acc = [(se.Integer(1), "sin" if isinstance(trig[0], se.sin) else "cos", trig[0].args[0])]
        for f in trig[1:]:
            kind = "sin" if isinstance(f, se.sin) else "cos"
            acc = [(c * c2, k2, a2) for c, k, a in acc for c2, k2, a2 in _product_to_sum(k, a, kind, f.args[0])]
        out.append(se.Mul(*rest) * se.Add(*[c * _trig(k, a) for c, k, a in acc]))
    return se.expand(se.Add(*out))


def group_by_atoms(expr, varsyms):
    """Sum of (transcendental factor) * (polynomial in the variables): terms of an expanded
    sum grouped by their non-polynomial factors, so each such factor is multiplied once."""
    if not isinstance(expr, se.Add):
        return expr
    groups: dict = {}
    for term in expr.args:
        factors = term.args if isinstance(term, se.Mul) else (term,)
        key, poly = [], []
        for f in factors:
            base = f.args[0] if isinstance(f, se.Pow) else f
            positive_power = not isinstance(f, se.Pow) or (isinstance(f.args[1], se.Integer) and f.args[1] > 0)
            polynomial = not (f.free_symbols & varsyms) or (base in varsyms and positive_power)
            (poly if polynomial else key).append(f)
        groups.setdefault(se.Mul(*key), []).append(se.Mul(*poly))
    return se.Add(*[k * se.Add(*v) for k, v in groups.items()])


# ------------------------------------------------------------------ the scene
def scene_expressions(scene: Scene, events=(), dynamics: bool = True) -> tuple[dict, object, dict]:
    """(expressions by location, time symbol, state symbol -> row) of ``scene`` with model
    symbols renamed to y[i], p[k] and folded parameters as numbers. Locations: ("kin", i) (the
    coordinates' rates, generalized speeds only), ("M", i, j) for the upper triangle, ("F", i),
    ("rate", k), ("event", e); ``dynamics`` False: without M and F (a rigid-body tree's come
    from its program, :func:`program_form`)."""
    eom = scene.eom
    require_symmetric(eom, "the Taylor method")
    model = eom.model
    n = model.nv
    sub = symbol_map(scene)
    time_symbol = se.Symbol(model.t.name)

    def c(e):
        e = se.sympify(e)
        return e.xreplace(sub) if sub else e

    exprs = {}
    if model.general:  # the coordinates' rates (generalized speeds)
        for i, k in enumerate(eom.qdot_se):
            exprs[("kin", i)] = c(k)
    if dynamics:
        for i in range(n):
            for j in range(i, n):
                exprs[("M", i, j)] = c(eom.M_se[i][j])
        for i in range(n):
            exprs[("F", i)] = c(eom.F_se[i])
    for k, (_, rate) in enumerate(eom.quadratures):
        exprs[("rate", k)] = c(rate)
    for e, ev in enumerate(events):
        exprs[("event", e)] = c(ev.expr)
    ny = model.nq + n + len(eom.quadratures)
    state = {se.Symbol(f"y[{i}]"): i for i in range(ny)}
    return exprs, time_symbol, state


def _where(scene: Scene, loc: tuple, events) -> str:
    eom = scene.eom
    names = [q.name for q in eom.model.v] if eom.general else [q.name for q in eom.model.coords]
    if loc[0] == "kin":
        return f"the kinematic equation of {eom.model.coords[loc[1]].name}"
    if loc[0] == "M":
        return f"the mass matrix entry M[{names[loc[1]]}, {names[loc[2]]}]"
    if loc[0] == "F":
        return f"the force F[{names[loc[1]]}]"
    if loc[0] == "rate":
        return f"the quadrature rate of {eom.quadratures[loc[1]][0]}"
    return f"event {events[loc[1]].name!r}"


def _decompose_form(exprs: dict, time_symbol, state: dict, n: int, nz: int, ne: int, form: str,
                    where, names: dict, nq: int | None = None) -> Decomposition:
    d = _Decomposer(state, time_symbol, n, nz, nq)
    d.names = names
    varsyms = d.varsyms
    entries = {}
    with progress.stage("taylor", total=len(exprs), unit=f"expressions, {form} form") as stage:
        for loc, e in exprs.items():  # one expression at a time: a loop point for progress and Ctrl-C
            d.where = where(loc)
            if form == "trig-linearized" and not d.is_const(e):
                e = group_by_atoms(linearize_trig(e), varsyms)
            entries[loc] = d.row(e) if loc[0] == "event" else d.node(e)
            stage.advance()
    return _assemble(d, entries, n, nz, ne, nq, form)


def _assemble(d: _Decomposer, entries: dict, n: int, nz: int, ne: int, nq: int | None, form: str) -> Decomposition:
    """The :class:`Decomposition` of the decomposer ``d``, the rows (or constants) of the
    equations' entries by location (:func:`scene_expressions`' locations)."""
    M = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(i, n):
            M[i][j] = M[j][i] = entries[("M", i, j)]
    decomposition = Decomposition(
        n=n, nz=nz, nrows=d.nrows, ops=d.ops, consts=d.consts, M=M,
        F=[entries[("F", i)] for i in range(n)], rates=[entries[("rate", k)] for k in range(nz)],
        events=[entries[("event", e)] for e in range(ne)],
        time_row=d.time_row, form=form, cost=0.0, labels=d.labels,
        kin=None if nq is None else [entries[("kin", i)] for i in range(nq)])
    decomposition.cost = cost(decomposition)
    return decomposition


def program_form(scene: Scene, events, where, names: dict) -> Decomposition:
    """The elementary operations of a rigid-body tree's equations taken from its recorded program
    (:func:`lagcodegen.formulation.kernels.tree_rhs`: composite rigid bodies for M, recursive
    Newton-Euler for the bias, eq. 3.16's M q'' = F with the model's other terms in closed form),
    statement by statement: each temporary is decomposed once, over the rows of the earlier ones,
    so the work and the operations are linear in the program's length (decomposing the tree's DAG
    expressions instead visits their shared subexpressions through symengine's hashing and
    comparisons, which on a 12-joint chain did not finish in 100 s). A temporary whose value is a
    constant (numbers and run-time parameters only) enters the later statements as that constant.
    The coordinates' rates (generalized speeds), the quadrature rates and the events are closed
    forms, decomposed as :func:`decompose` does."""
    from ...formulation.kernels import tree_rhs
    eom = scene.eom
    model = eom.model
    n, nz, ne = model.nv, len(eom.quadratures), len(events)
    nq = model.nq if eom.general else None
    exprs, time_symbol, state = scene_expressions(scene, events, dynamics=False)
    block = tree_rhs(eom, symbol_map(scene))
    d = _Decomposer(state, time_symbol, n, nz, nq)
    d.names = names
    known: dict = {}  # a temporary with a constant value -> that constant (its expression or number)

    def node(e):
        sub = {u: known[u] for u in e.free_symbols if u in known}
        return d.node(e.xreplace(sub) if sub else e)
    entries = {}
    closed = [(loc, e) for loc, e in exprs.items() if loc[0] == "kin"]
    closed_after = [(loc, e) for loc, e in exprs.items() if loc[0] != "kin"]
    total = len(closed) + len(block.defs) + len(block.targets) + len(closed_after)
    with progress.stage("taylor", total=total, unit="statements, tree program") as stage:
        for loc, e in closed:
            d.where = where(loc)
            entries[loc] = d.node(e)
            stage.advance()
        d.where = "the rigid-body tree's recursions"
        for sym, e in block.defs:
            entry = node(e)
            if isinstance(entry, int):
                d.state[sym] = entry
                d.varsyms.add(sym)
            else:
                known[sym] = d.consts[entry.index] if isinstance(entry, Const) else entry
            stage.advance()
        for target, e in zip(block.targets, block.exprs):
            d.where = where(target)
            entries[target] = node(e)
            stage.advance()
        for loc, e in closed_after:
            d.where = where(loc)
            entries[loc] = d.row(e) if loc[0] == "event" else d.node(e)
            stage.advance()
    return _assemble(d, entries, n, nz, ne, nq, "program")


def fuse_products(d: Decomposition) -> Decomposition:
    """``d`` with each product (``mul``) whose row only one linear combination uses folded into
    that combination, which becomes a ``dot``: the products' Cauchy sums share one loop over
    the orders (one loop instead of one per product; each product summed in the same order as
    alone, so the jet is the same to the last bit)."""
    uses: dict[int, int] = {}

    def use(entry):
        if isinstance(entry, int) and not isinstance(entry, bool):
            uses[entry] = uses.get(entry, 0) + 1

    for op in d.ops:
        for r in op.args:
            use(r)
    for entry in [e for row in d.M for e in row] + list(d.F) + list(d.rates) + list(d.events) + list(d.kin or ()):
        use(entry)
    products = {op.out[0]: op for op in d.ops if op.kind == "mul"}
    fused: set[int] = set()
    ops = []
    for op in d.ops:
        if op.kind == "lin" and any(uses.get(r) == 1 and r in products for r in op.args):
            pairs = tuple(products[r].args if uses.get(r) == 1 and r in products else None for r in op.args)
            fused |= {r for r, pair in zip(op.args, pairs) if pair is not None}
            op = Op("dot", op.out, op.args, op.coefs, op.const, op.expr, pairs)
        ops.append(op)
    d.ops = [op for op in ops if op.out[0] not in fused]
    d.cost = cost(d)
    return d


def cost(d: Decomposition) -> float:
    """Work per order, in convolutions: the operations plus the mass-matrix convolution
    sum_j M_[j] a_[k-j] (none for constant entries)."""
    total = sum(COST[op.kind] * (len(op.args) if op.kind == "lin" else 1) for op in d.ops)
    total += sum(COST["lin"] * len(op.args) + COST["mul"] * sum(p is not None for p in op.pairs)
                 for op in d.ops if op.kind == "dot")
    total += sum(1.0 for row in d.M for entry in row if isinstance(entry, int))
    return total


def decompose(scene: Scene, events=(), form: str | None = None, fuse: bool = True) -> Decomposition:
    """The elementary operations of ``scene`` (M, F, quadrature rates) and of the ``events``
    (objects with ``name`` and ``expr``): a rigid-body tree's from its recorded program
    (:func:`program_form`), other models' in the cheaper of the two forms of their expressions
    (``form``: "derived" or "trig-linearized" to force one; "program" a tree's default);
    ``fuse``: products used by one linear combination only computed in its loop
    (:func:`fuse_products`)."""
    eom = scene.eom
    names = {v: se.Symbol(str(k)) for k, v in symbol_map(scene).items() if isinstance(v, se.Symbol)}

    def where(loc):
        return _where(scene, loc, events)

    if form not in (None, "program", "derived", "trig-linearized"):
        raise ModelError(f"decompose: unknown form {form!r} (forms: 'program', 'derived', 'trig-linearized')")
    if eom.tree is not None and form in (None, "program"):
        return _fused(program_form(scene, events, where, names), fuse)
    if form == "program":
        raise ModelError(f"decompose: form 'program' is a rigid-body tree's; model {eom.model.name!r} has no tree "
                         "(forms: 'derived', 'trig-linearized')")
    n, nz = eom.model.nv, len(eom.quadratures)
    nq = eom.model.nq if eom.general else None
    exprs, time_symbol, state = scene_expressions(scene, events)
    forms = (form,) if form else ("derived", "trig-linearized")
    best = None
    for f in forms:
        d = _decompose_form(exprs, time_symbol, state, n, nz, len(events), f, where, names, nq)
        if best is None or d.cost < best.cost:
            best = d
    return _fused(best, fuse)


def _fused(d: Decomposition, fuse: bool) -> Decomposition:
    return fuse_products(d) if fuse else d
