"""symengine expressions -> the operation tree of :mod:`.ir`, once, in the evaluation order of
the generated code.

Sums and products become chains of binary operations, left to right, in the order symengine's
C printer lists their terms and factors: the terms of a sum by symengine's total order of
expressions (:func:`compare`: by type, in the order of symengine's type codes, then within the
type), the factors of a product in the order of its own dictionary (the order of ``Mul.args``),
the reciprocal factors divided at the end; a written minus binds to the first factor, a term
written with a leading minus is subtracted; rational coefficients are divisions of two literals
and floating-point constants exact literals. So the C text of the tree is the text symengine's
printer writes (byte for byte: the generated C did not change with the tree), and every backend
evaluates the same operations in the same order.
"""

from __future__ import annotations

import functools
from typing import Callable

import symengine as se

from ..errors import ModelError
from .ir import (FUNCTIONS, Assign, BinOp, Call, Compare, Integer, Logic, Name, Neg, Node, Not, Number, Power,
                 Ratio, Select, Sign, symbol_node, target_nodes)

_CLASS_FUNCTION = {"Abs": "abs", "Max": "max", "Min": "min"}


# ----------------------------------------------------------------------------- symengine's order
# symengine's C printer lists the terms of a sum by its total order of expressions (type first,
# in the order of symengine's type codes, then per type); the factors of a product in the order
# of the product's dictionary, which is also the order of ``Mul.args``.
_TYPE_ORDER = (
    "Integer", "Rational", "Complex", "ComplexDouble", "RealMPFR", "ComplexMPC", "RealDouble", "Infty", "NaN",
    "NumberWrapper", "Symbol", "Dummy", "Mul", "Add", "Pow", "UIntPoly", "MIntPoly", "URatPoly", "UExprPoly",
    "MExprPoly", "GaloisField", "UnivariateSeries", "Log", "Conjugate", "Constant", "Sign", "Floor", "Ceiling",
    "Sin", "Cos", "Tan", "Cot", "Csc", "Sec", "ASin", "ACos", "ASec", "ACsc", "ATan", "ACot", "ATan2", "Sinh",
    "Csch", "Cosh", "Sech", "Tanh", "Coth", "ASinh", "ACsch", "ACosh", "ATanh", "ACoth", "ASech", "LambertW",
    "Zeta", "Dirichlet_eta", "KroneckerDelta", "LeviCivita", "Erf", "Erfc", "Gamma", "PolyGamma", "LowerGamma",
    "UpperGamma", "LogGamma", "Beta", "FunctionSymbol", "FunctionWrapper", "Derivative", "Subs", "Abs", "Max",
    "Min", "EmptySet", "FiniteSet", "Interval", "Complexes", "Reals", "Rationals", "Integers", "Naturals",
    "Naturals0", "ConditionSet", "Union", "Intersection", "Complement", "ImageSet", "Piecewise", "UniversalSet",
    "Contains", "BooleanAtom", "Not", "And", "Or", "Xor", "Equality", "Unequality", "LessThan", "StrictLessThan",
    "Truncate")
_RANK = {name: k for k, name in enumerate(_TYPE_ORDER)}
#: Python class names of the symengine wrapper -> symengine type names.
_PY_TYPE = {"Zero": "Integer", "One": "Integer", "NegativeOne": "Integer", "Half": "Rational", "log": "Log",
            "Pi": "Constant", "Exp1": "Constant", "EulerGamma": "Constant", "Catalan": "Constant",
            "GoldenRatio": "Constant", "sign": "Sign", "floor": "Floor", "ceiling": "Ceiling", "gamma": "Gamma",
            "loggamma": "LogGamma", "erf": "Erf", "erfc": "Erfc", "BooleanTrue": "BooleanAtom",
            "BooleanFalse": "BooleanAtom", "truncate": "Truncate", "conjugate": "Conjugate"}
_PY_TYPE.update((n, n.capitalize()) for n in "sin cos tan cot csc sec sinh csch cosh sech tanh coth".split())
_PY_TYPE.update((n, "A" + n[1:].capitalize()) for n in
                "asin acos asec acsc atan acot atan2 asinh acsch acosh atanh acoth asech".split())


def _type(e) -> str:
    name = type(e).__name__
    return _PY_TYPE.get(name, name)


def _sign(a, b) -> int:
    return (a > b) - (a < b)


#: Products and sums already taken apart (:func:`_mul_dict`, :func:`_add_dict`) within one
#: :func:`expression`: sorting a sum's terms compares each product several times. Cleared per
#: expression and when full.
_PARTS: dict = {}
_PARTS_MAX = 1 << 16


def _memo(f):
    def parts(e) -> tuple:
        key = (f, e)
        hit = _PARTS.get(key)
        if hit is None:
            if len(_PARTS) >= _PARTS_MAX:
                _PARTS.clear()
            hit = _PARTS[key] = f(e)
        return hit
    parts.__doc__ = f.__doc__
    return parts


@_memo
def _mul_dict(e) -> tuple:
    """(coefficient, ((base, exponent), ...) in the product's dictionary order). A factor that is a
    power with exponent 1 in the dictionary (a product built without simplification) stays one."""
    (coef,) = e.as_coefficients_dict().values()
    powers = e.as_powers_dict()
    items = []
    for a in e.args:
        if a.is_Number:
            continue
        if a.is_Pow and powers.get(a) != 1:
            items.append(tuple(a.args))
        else:
            items.append((a, se.Integer(1)))
    return coef, tuple(items)


@_memo
def _add_dict(e) -> tuple:
    """(constant, ((term, coefficient), ...)) of a sum, terms unordered."""
    d = e.as_coefficients_dict()
    one = se.Integer(1)
    return d[one], tuple((k, v) for k, v in d.items() if not (k == one and k.is_Number))


def _keyed(items: list) -> list:
    """``items`` (key, value) in the order of symengine's ordered dictionaries (a set of the keys)."""
    if len(items) < 2:
        return items
    by_key = {k: (k, v) for k, v in items}
    return [by_key[k] for k in se.FiniteSet(*by_key).args]


def _is_int(e, value: int) -> bool:
    """``e`` is the Integer ``value`` (symengine's structural test: 1.0 is not the Integer 1)."""
    return _type(e) == "Integer" and int(e) == value


def _number_value(e):
    if _type(e) == "Integer":
        return int(e)
    if _type(e) == "Rational":
        p, q = e.as_numer_denom()
        return int(p), int(q)
    return float(e)


def compare(a, b) -> int:
    """symengine's total order of expressions (-1, 0, 1): by type, then within the type."""
    if a == b:
        return 0
    ta, tb = _type(a), _type(b)
    if ta != tb:
        if ta not in _RANK or tb not in _RANK:
            raise ModelError(f"cannot generate code for {a if ta not in _RANK else b} (unsupported expression)")
        return _sign(_RANK[ta], _RANK[tb])
    if ta in ("Symbol", "Constant", "Dummy"):
        return _sign(str(a), str(b))
    if ta == "Rational":
        (p, q), (r, s) = _number_value(a), _number_value(b)
        return _sign(p * s, r * q)
    if a.is_Number:
        return _sign(_number_value(a), _number_value(b))
    if ta in ("Mul", "Add"):
        ca, da = (_mul_dict if ta == "Mul" else _add_dict)(a)
        cb, db = (_mul_dict if ta == "Mul" else _add_dict)(b)
        if len(da) != len(db):
            return -1 if len(da) < len(db) else 1
        c = compare(ca, cb)
        if c:
            return c
        if ta == "Add":
            da, db = _keyed(da), _keyed(db)
        for (ka, va), (kb, vb) in zip(da, db):
            c = compare(ka, kb) or compare(va, vb)
            if c:
                return c
        return 0
    aa, ba = a.args, b.args
    if len(aa) != len(ba):
        return -1 if len(aa) < len(ba) else 1
    for x, y in zip(aa, ba):
        c = compare(x, y)
        if c:
            return c
    return 0


_ORDER_KEY = functools.cmp_to_key(lambda x, y: compare(x[0], y[0]))


# ----------------------------------------------------------------------------- symengine -> tree
_PLACEHOLDER = "LCGNUM{}X"
_INT_MAX = 2**31 - 1
_HALF, _THIRD = se.Rational(1, 2), se.Rational(1, 3)


def _chain(first: Node, factors: list) -> Node:
    node = first
    for op, f in factors:
        node = _times(node, op, f)
    return node


def _times(acc: Node, op: str, factor: Node) -> Node:
    """``acc op factor`` as the text ``acc*factor`` reads: a product chain ``factor`` continues
    the chain of ``acc`` (a product nested in a product is written without parentheses)."""
    if op == "*" and isinstance(factor, BinOp) and factor.op in "*/":
        return BinOp(factor.op, _times(acc, op, factor.left), factor.right)
    return BinOp(op, acc, factor)


def _strip_minus(node: Node, in_product: bool = False) -> Node | None:
    """``node`` without the minus its text starts with, or None if the text starts otherwise."""
    if isinstance(node, BinOp):
        if in_product and node.op in "+-":
            return None  # parenthesized
        inner = _strip_minus(node.left, in_product or node.op in "*/")
        return None if inner is None else BinOp(node.op, inner, node.right)
    if isinstance(node, Neg):
        return node.arg
    if isinstance(node, Integer) and node.value < 0:
        return Integer(-node.value)
    if isinstance(node, Ratio) and node.num < 0 and not in_product:
        return Ratio(-node.num, node.den)
    return None


def _plus(acc: Node, term: Node, fold: bool = True) -> Node:
    """``acc + term`` as the text ``acc + <term>`` reads: a sum ``term`` continues the sum of
    ``acc``; with ``fold``, a term written with a leading minus is subtracted."""
    if isinstance(term, BinOp) and term.op in "+-":
        return BinOp(term.op, _plus(acc, term.left, fold), term.right)
    stripped = _strip_minus(term) if fold else None
    if stripped is not None:
        return BinOp("-", acc, stripped)
    return BinOp("+", acc, term)


def plus(acc: Node, term: Node) -> Node:
    """``acc + term`` evaluated as ``acc`` followed by the terms of the sum ``term`` one by one
    (the order of ``acc + t1 + t2 ...``)."""
    return _plus(acc, term, fold=False)


def negate_first(node: Node) -> Node:
    """The tree of ``-`` written before the text of ``node``: the minus binds to the first operand
    of a product or quotient chain, else to the whole node."""
    if isinstance(node, BinOp) and node.op in "*/":
        return BinOp(node.op, negate_first(node.left), node.right)
    if isinstance(node, Neg):  # a value written into its reader (a recorded program's) may be one
        return node.arg
    return Neg(node)

class _Builder:
    def __init__(self, resolve: Callable[[str], Node | None] | None, numbers: dict):
        self.resolve = resolve
        self.numbers = numbers

    def symbol(self, e) -> Node:
        name = e.name
        if name in self.numbers:
            return self.numbers[name]
        if self.resolve is not None:
            node = self.resolve(name)
            if node is not None:
                return node
        return symbol_node(name)

    def build(self, e) -> Node:
        t = _type(e)
        method = getattr(self, "_" + t, None)
        if method is None:
            name = _CLASS_FUNCTION.get(type(e).__name__, type(e).__name__)
            if name in FUNCTIONS:
                return Call(name, tuple(self.build(a) for a in e.args))
            raise ModelError(f"cannot generate code for {e} ({type(e).__name__} is not supported)")
        return method(e)

    def _Symbol(self, e):
        return self.symbol(e)

    def _Integer(self, e):
        return Integer(int(e))

    def _Rational(self, e):
        p, q = _number_value(e)
        return Ratio(p, q)

    def _RealDouble(self, e):
        return Number(float(e))

    def _Constant(self, e):
        if e == se.pi:
            return Call("acos", (Neg(Integer(1)),))
        if e == se.E:
            return Call("exp", (Integer(1),))
        raise ModelError(f"cannot generate code for the constant {e}")

    def _BooleanAtom(self, e):
        return Number(1.0 if e == se.true else 0.0)

    def _Pow(self, e):
        base, exp = e.args
        if exp == -1 and base != se.E:
            return BinOp("/", Integer(1), self.build(base))
        return self.power(base, exp)

    def power(self, base, exp) -> Node:
        if base == se.E:
            return Call("exp", (self.build(exp),))
        if exp == _HALF:
            return Call("sqrt", (self.build(base),))
        if exp == _THIRD:
            return Call("cbrt", (self.build(base),))
        return Power(self.build(base), self.build(exp))

    def _Mul(self, e):
        coef, items = _mul_dict(e)
        first = None
        num: list = []
        den: list = []
        negate = False
        if _is_int(coef, -1):
            negate = True
        elif not _is_int(coef, 1):
            first = self.build(coef)
        for base, exp in items:
            if _type(exp) in ("Integer", "Rational") and exp.is_negative and base != se.E:
                den.append(self.build(base) if exp == -1 else self.power(base, -exp))
            else:
                f = self.build(base) if exp == 1 else self.power(base, exp)
                if first is None:
                    first = f
                else:
                    num.append(("*", f))
        if first is None:
            first = Integer(1)
        node = _chain(first, num)
        if negate:
            node = negate_first(node)
        if den:
            node = BinOp("/", node, _chain(den[0], [("*", d) for d in den[1:]]))
        return node

    def _Add(self, e):
        coef, items = _add_dict(e)
        items = sorted(items, key=_ORDER_KEY)
        node = None if _is_int(coef, 0) else self.build(coef)
        for key, c in items:
            k = self.build(key)
            if _is_int(c, 1):
                term, minus = k, False
            elif _is_int(c, -1):
                term, minus = k, True
            else:
                cn = self.build(c)
                minus = _type(c) == "Integer" and c.is_negative
                if minus:
                    cn = Integer(-int(c))
                term = _prepend(cn, k)
            if node is None:
                node = negate_first(term) if minus else term
            elif minus:
                node = BinOp("-", node, term)
            else:
                node = _plus(node, term)
        return node

    def _Sign(self, e):
        return Sign(self.build(e.args[0]))

    def _Max(self, e):
        return self._minmax("max", se.Max, e.args)

    def _Min(self, e):
        return self._minmax("min", se.Min, e.args)

    def _minmax(self, name, cls, args):
        rest = args[1:]
        inner = self.build(rest[0] if len(rest) == 1 else cls(*rest))
        return Call(name, (self.build(args[0]), inner))

    def _Piecewise(self, e):
        args = e.args
        pairs = [(args[k], args[k + 1]) for k in range(0, len(args), 2)]
        if pairs[-1][1] != se.true:
            raise ModelError(f"cannot generate code for {e}: a piecewise expression needs a last case (value, True)")
        return Select(tuple((self.build(c), self.build(v)) for v, c in pairs[:-1]), self.build(pairs[-1][0]))

    def _Equality(self, e):
        return Compare("==", *map(self.build, e.args))

    def _Unequality(self, e):
        return Compare("!=", *map(self.build, e.args))

    def _LessThan(self, e):
        return Compare("<=", *map(self.build, e.args))

    def _StrictLessThan(self, e):
        return Compare("<", *map(self.build, e.args))

    def _And(self, e):
        return Logic("and", tuple(self.build(a) for a in e.args))

    def _Or(self, e):
        return Logic("or", tuple(self.build(a) for a in e.args))

    def _Not(self, e):
        return Not(self.build(e.args[0]))


def _prepend(coef: Node, node: Node) -> Node:
    """``coef * node`` as written: the coefficient becomes the first factor of the chain."""
    if isinstance(node, BinOp) and node.op in "*/":
        return BinOp(node.op, _prepend(coef, node.left), node.right)
    return BinOp("*", coef, node)


def expression(expr, resolve: Callable[[str], Node | None] | None = None) -> Node:
    """The tree of a symengine expression.

    Floating-point constants (and integers too large for a C int) are exact :class:`Number`
    literals. ``resolve(name)`` may map a symbol's name to a node (e.g. the values of a program
    stored elsewhere); by default ``y[3]`` is Element("y", 3) and any other name a :class:`Name`.
    The order of operations depends only on the expression (the symbols' names as given), not
    on ``resolve``.
    """
    expr = se.sympify(expr)
    _PARTS.clear()
    numbers = [a for a in expr.atoms(se.RealDouble, se.Integer)
               if isinstance(a, se.RealDouble) or abs(int(a)) > _INT_MAX]
    table = {}
    if numbers:
        placeholders = {}
        for k, a in enumerate(numbers):
            name = _PLACEHOLDER.format(k)
            placeholders[a] = se.Symbol(name)
            table[name] = Number(float(a))
        expr = expr.xreplace(placeholders)
    return _Builder(resolve, table).build(expr)

def _number_node(e) -> Node | None:
    t = _type(e)
    if t == "Integer":
        v = int(e)
        return Integer(v) if abs(v) <= _INT_MAX else Number(float(v))
    if t == "Rational":
        return Ratio(*_number_value(e))
    if t == "RealDouble":
        return Number(float(e))
    return None


_UNARY_FUNCTIONS = frozenset(("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log"))


def statement(expr, resolve: Callable[[str], Node | None] | None = None) -> Node:
    """The tree of one statement of a straight-line program (a sum of numbers times operands, a
    product, a power or a function of operands: :meth:`lagcodegen.formulation.tangent.Program.atom`),
    its operations in the order of the statement's own arguments (no reordering: the operands
    may be trees written into it by ``resolve``, as :func:`expression`'s). Anything else is
    :func:`expression`'s."""
    def leaf(a) -> Node | None:
        if a.is_Symbol:
            name = a.name
            node = resolve(name) if resolve is not None else None
            return node if node is not None else symbol_node(name)
        return _number_node(a) if a.is_Number else None

    def product(args) -> Node | None:
        first, num, den, negate = None, [], [], False
        for a in args:
            if a.is_Number:
                if _is_int(a, -1):
                    negate = not negate
                    continue
                if _is_int(a, 1):
                    continue
            elif a.is_Pow:
                base, exp = a.args
                b = leaf(base)
                if b is None or not exp.is_Number or base == se.E:
                    return None
                if _is_int(exp, -1):
                    den.append(b)
                    continue
                f = (Call("sqrt", (b,)) if exp == _HALF else Call("cbrt", (b,)) if exp == _THIRD
                     else Power(b, _number_node(exp)))
                if first is None:
                    first = f
                else:
                    num.append(("*", f))
                continue
            f = leaf(a)
            if f is None:
                return None
            if first is None:
                first = f
            else:
                num.append(("*", f))
        node = _chain(first if first is not None else Integer(1), num)
        if negate:
            node = negate_first(node)
        if den:
            node = BinOp("/", node, _chain(den[0], [("*", d) for d in den[1:]]))
        return node

    def term(a) -> Node | None:
        return product(a.args) if a.is_Mul else product((a,))

    node = None
    if expr.is_Add:
        for a in expr.args:
            t = term(a)
            if t is None:
                node = None
                break
            node = t if node is None else _plus(node, t)
    elif expr.is_Mul or expr.is_Pow:
        node = term(expr)
    elif type(expr).__name__ in _UNARY_FUNCTIONS:
        arg = leaf(expr.args[0])
        if arg is not None:
            node = Call(type(expr).__name__, (arg,))
    return node if node is not None else expression(expr, resolve)


def block_statements(block, eliminate: Callable) -> list[Assign]:
    """The assignments of a kernel :class:`~lagcodegen.formulation.kernels.Block` after
    common-subexpression elimination ``eliminate``: the temporaries (local Names), then the targets."""
    return statements([target_nodes(t) for t in block.targets], block.exprs, eliminate)


def statements(targets: list, exprs: list, eliminate: Callable, resolve=None,
               temporary: Callable[[str], Node] | None = None) -> list[Assign]:
    """The assignments ``targets[k] = exprs[k]`` (targets: tuples of nodes) after
    common-subexpression elimination ``eliminate`` (returns (replacements, reduced)): the
    temporaries first (local Names, or ``temporary(name)``), then the targets."""
    if not exprs:
        return []
    repl, reduced = eliminate(list(exprs))
    out = []
    for sym, e in repl:
        target = Name(str(sym)) if temporary is None else temporary(str(sym))
        out.append(Assign((target,), expression(e, resolve), local=temporary is None))
    out += [Assign(tuple(tg), expression(e, resolve)) for tg, e in zip(targets, reduced)]
    return out

