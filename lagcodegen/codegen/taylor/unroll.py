"""The C text of a small model's Taylor jet with its first orders unrolled: order k of every
elementary operation (:mod:`~lagcodegen.codegen.taylor.decompose`) written out for each
k = 0..K-1 with constant indices, each Cauchy sum as a balanced (pairwise) tree of its terms.

Why: for a small model the jet's time is the latency of its sums, not their operations. Inside
the loop over the orders, a convolution of length k is a chain of k dependent additions, and
order k + 1 waits for it (s_[k+1] of sin q needs c_[k] of cos q, which needs the whole sum of
order k). Written out, a sum of k terms is a tree of depth log2 k, and the compiler and the
processor overlap the independent products of an order with the chain of the one before (the
same code heyoka generates for a fixed order in its default mode, here for every order at once:
the run's order is chosen at run time, and the loop takes over beyond K). Rounding differs from
the loop's sums (another order of the same terms), not its accuracy.

The recurrences are those of ``templates/taylor/recurrences.c.j2``; the product j u_j of a
state row u (q or q') is read from its derivative's row instead (j q_[j] = q'_[j-1],
j q'_[j] = q''_[j-1]), one multiplication fewer per term.
"""

from __future__ import annotations

from .decompose import Const, Decomposition

#: Orders written out (0..UNROLL_ORDERS-1): every order the tolerances choose (at most 22 at
#: rtol = machine epsilon, see tl_order) and the one more of a run with events.
UNROLL_ORDERS = 23

#: The largest jet written out, in product terms of its Cauchy sums over the written-out orders
#: (:func:`terms`). The pendulum's 531 terms compile to 16 kB in 0.6 s and cut its C run's time
#: by about a quarter; the double pendulum's 2960 (82 kB, past a processor's 32 kB instruction
#: cache, 4 s of gcc) ran as fast as the loop or up to 10% slower, the 3-link pendulum's 6906
#: 15-20% slower: from two coupled coordinates on, an order has independent work enough to hide
#: the sums' latency.
MAX_TERMS = 1200


def _u(row: int, k: int) -> str:
    return f"U({row})[{k}]"


def pairwise(terms: list[str]) -> str:
    """The sum of ``terms`` (C text) as a balanced tree: adjacent pairs, then pairs of pairs."""
    if not terms:
        return "0.0"
    while len(terms) > 1:
        nxt = [f"({terms[i]} + {terms[i + 1]})" for i in range(0, len(terms) - 1, 2)]
        if len(terms) % 2:
            nxt.append(terms[-1])
        terms = nxt
    return terms[0]


class _Printer:
    """Order k of each operation of ``d``, as C statements."""

    def __init__(self, d: Decomposition, coef):
        self.d = d
        self.coef = coef
        n, ny, nq = d.n, d.ny, d.nq
        # the row holding the derivative of each state row's series: j x_[j] = x'_[j-1]
        if d.kin is None:
            self.deriv = {i: n + i for i in range(n)} | {n + i: ny + i for i in range(n)}
        else:  # generalized speeds: q' = k(q, v, t), where k is a row
            self.deriv = {i: k for i, k in enumerate(d.kin) if isinstance(k, int) and not isinstance(k, bool)}
            self.deriv |= {nq + i: ny + i for i in range(n)}

    def at(self, e, k: int) -> str:
        """An entry (row, run constant or number) at order k."""
        if isinstance(e, int) and not isinstance(e, bool):
            return _u(e, k)
        if not isinstance(e, Const) and e == 0:
            return "0.0"
        return self.coef(e) if k == 0 else "0.0"

    def jterm(self, u: int, j: int) -> str:
        """j u_[j]."""
        if u in self.deriv:
            return _u(self.deriv[u], j - 1)
        return f"{j}.0 * {_u(u, j)}"

    def scaled(self, u: int, x: int, k: int, sign: str = "") -> str:
        """sign (1/k) sum_{j=1..k} j u_[j] x_[k-j] (sin/cos, sinh/cosh, exp, tan), its newest term
        (x_[k-1], of the previous order) split off: sign (1/k) (sum_{j>=2}) + (sign u_[1]/k) x_[k-1],
        one multiplication and one addition after x_[k-1] instead of the tree's depth."""
        newest = f"({sign}{self.jterm(u, 1)} * (1.0 / {k})) * {_u(x, k - 1)}"
        if k == 1:
            return newest
        rest = pairwise([f"{self.jterm(u, j)} * {_u(x, k - j)}" for j in range(2, k + 1)])
        return f"{sign}({rest}) * (1.0 / {k}) + {newest}"

    def cauchy(self, a: int, b: int, k: int) -> str:
        return pairwise([f"{_u(a, j)} * {_u(b, k - j)}" for j in range(k + 1)])

    def lin(self, op, k: int, values: list[str]) -> str:
        parts = []
        for c, v in zip(op.coefs, values):
            text = self.coef(c)
            parts.append(v if text in ("1.0", "1") else f"-{v}" if text in ("(-1.0)", "(-1)") else f"{text} * {v}")
        if op.const is not None and k == 0:
            parts.append(self.coef(op.const))
        return " + ".join(parts) if parts else "0.0"

    def op(self, op, k: int) -> list[str]:
        o = op.out[0]
        kind = op.kind
        a = op.args
        inv_k = f"(1.0 / {k})"
        if kind == "cst":
            return [f"{_u(o, k)} = {self.coef(op.const) if k == 0 else '0.0'};"]
        if kind == "lin":
            return [f"{_u(o, k)} = {self.lin(op, k, [_u(x, k) for x in a])};"]
        if kind == "dot":
            values = [_u(x, k) if pr is None else f"({self.cauchy(pr[0], pr[1], k)})" for x, pr in zip(a, op.pairs)]
            return [f"{_u(o, k)} = {self.lin(op, k, values)};"]
        if kind == "mul":
            return [f"{_u(o, k)} = {self.cauchy(a[0], a[1], k)};"]
        if kind == "sqr":
            return [f"{_u(o, k)} = {self._sqr(a[0], k)};"]
        if kind in ("div", "cdiv"):
            b = a[-1]
            num = (_u(a[0], k) if kind == "div" else (self.coef(op.const) if k == 0 else "0.0"))
            if k == 0:
                return [f"{_u(o, 0)} = {num} / {_u(b, 0)};"]
            return [f"{_u(o, k)} = ({num} - {pairwise([f'{_u(o, k - j)} * {_u(b, j)}' for j in range(1, k + 1)])})"
                    f" / {_u(b, 0)};"]
        if kind in ("sincos", "sinhcosh"):
            s, c = op.out
            if k == 0:
                f, g = ("sin", "cos") if kind == "sincos" else ("sinh", "cosh")
                return [f"{_u(s, 0)} = {f}({_u(a[0], 0)});", f"{_u(c, 0)} = {g}({_u(a[0], 0)});"]
            sign = "-" if kind == "sincos" else ""
            return [f"{_u(s, k)} = {self.scaled(a[0], c, k)};", f"{_u(c, k)} = {self.scaled(a[0], s, k, sign)};"]
        if kind == "exp":
            if k == 0:
                return [f"{_u(o, 0)} = exp({_u(a[0], 0)});"]
            return [f"{_u(o, k)} = {self.scaled(a[0], o, k)};"]
        if kind == "log":
            if k == 0:
                return [f"{_u(o, 0)} = log({_u(a[0], 0)});"]
            s = pairwise([f"{self.jterm(o, j)} * {_u(a[0], k - j)}" for j in range(1, k)])
            return [f"{_u(o, k)} = ({_u(a[0], k)} - ({s}) * {inv_k}) / {_u(a[0], 0)};"]
        if kind == "pow":
            al = self.coef(op.const)
            if k == 0:
                return [f"{_u(o, 0)} = pow({_u(a[0], 0)}, {al});"]
            s = pairwise([f"({k}.0 * {al} - {j}.0 * ({al} + 1.0)) * {_u(a[0], k - j)} * {_u(o, j)}"
                          for j in range(k)])
            return [f"{_u(o, k)} = ({s}) / ({k}.0 * {_u(a[0], 0)});"]
        if kind == "sqrt":
            if k == 0:
                return [f"{_u(o, 0)} = sqrt({_u(a[0], 0)});"]
            terms = [f"{_u(o, k - j)} * {_u(o, j)}" for j in range(1, (k - 1) // 2 + 1)]
            s = f"2.0 * ({pairwise(terms)})" if terms else "0.0"
            if k % 2 == 0:
                s = f"{s} + {_u(o, k // 2)} * {_u(o, k // 2)}"
            return [f"{_u(o, k)} = ({_u(a[0], k)} - ({s})) / (2.0 * {_u(o, 0)});"]
        if kind == "tan":
            t, c = op.out
            if k == 0:
                return [f"{_u(t, 0)} = tan({_u(a[0], 0)});", f"{_u(c, 0)} = {_u(t, 0)} * {_u(t, 0)};"]
            return [f"{_u(t, k)} = {_u(a[0], k)} + {self.scaled(a[0], c, k)};", f"{_u(c, k)} = {self._sqr(t, k)};"]
        raise ValueError(f"no unrolled recurrence for operation kind {kind!r}")

    def _sqr(self, a: int, k: int) -> str:
        terms = [f"{_u(a, j)} * {_u(a, k - j)}" for j in range((k + 1) // 2)]
        s = f"2.0 * ({pairwise(terms)})" if terms else ""
        if k % 2 == 0:
            s = f"{s} + {_u(a, k // 2)} * {_u(a, k // 2)}" if s else f"{_u(a, k // 2)} * {_u(a, k // 2)}"
        return s

    def forces(self, k: int) -> list[str]:
        """r_i = F_i,[k] - sum_{j=1..k} M_ij,[j] q''_[k-j] over the non-constant entries of M."""
        d = self.d
        lines = []
        for i in range(d.n):
            terms = [f"{_u(m, j)} * {_u(d.ny + jj, k - j)}" for jj in range(d.n)
                     for m in [d.M[i][jj]] if isinstance(m, int) and not isinstance(m, bool)
                     for j in range(1, k + 1)]
            rhs = self.at(d.F[i], k)
            lines.append(f"r[{i}] = {rhs} - ({pairwise(terms)});" if terms else f"r[{i}] = {rhs};")
        return lines


def terms(d: Decomposition, orders: int = UNROLL_ORDERS) -> int:
    """About how many product terms the unrolled orders hold: the cost per order (in
    convolutions) times sum_k k."""
    return int(d.cost * orders * (orders - 1) / 2)


def unrolled_orders(d: Decomposition, coef, orders: int = UNROLL_ORDERS) -> list[list[str]]:
    """The C statements of orders 0..orders-1 of ``d``'s operations and of the forces r
    (before the solve with M_[0]); ``coef`` prints a coefficient."""
    p = _Printer(d, coef)
    return [[line for op in d.ops for line in p.op(op, k)] + p.forces(k) for k in range(orders)]
