"""The backends are peers printing one operation tree: no backend imports or parses another's
output, each printer has a method per node kind, and the tree's C text is symengine's own."""

import random
import re
import typing

import numpy as np
import pytest
import symengine as se

from lagcodegen import ModelError
from lagcodegen.codegen import ir, lowering
from lagcodegen.codegen.c import CPrinter, c_expr
from lagcodegen.codegen.fortran import FortranPrinter
from lagcodegen.codegen.languages import BACKENDS, backend, generate_code

# No backend imports another or parses printed text: tests/test_layout.py (every registered backend).


def test_every_printer_prints_every_node_kind():
    kinds = [k.__name__ for k in typing.get_args(ir.Node)]
    assert len(kinds) == 14
    for printer in (CPrinter, FortranPrinter):
        missing = [k for k in kinds if not hasattr(printer, f"_print_{k}")]
        assert not missing, f"{printer.__name__} lacks {missing}"


def test_registry_maps_names_to_backend_classes():
    assert set(BACKENDS) == {"c", "fortran"}
    for name, cls in BACKENDS.items():
        assert cls.name == name and all(callable(getattr(cls, m)) for m in ("generate", "check_prefix",
                                                                           "constrained_source"))
    assert isinstance(backend("fortran"), BACKENDS["fortran"])
    with pytest.raises(ModelError, match="cobol"):
        generate_code(None, "cobol")


# ------------------------------------------------------------------ the tree's C text is symengine's
_PLACEHOLDER = re.compile(r"LCGNUM(\d+)X")


def symengine_text(expr):
    """symengine's own C text with every float printed exactly (the reference the generated C
    was written with before the tree: numbers replaced by placeholder symbols, printed, put back)."""
    expr = se.sympify(expr)
    numbers = [a for a in expr.atoms(se.RealDouble, se.Integer)
               if isinstance(a, se.RealDouble) or abs(int(a)) > 2**31 - 1]
    table = {}
    for k, a in enumerate(numbers):
        text = repr(float(a))
        text += "" if any(ch in text for ch in ".e") else ".0"
        table[k] = f"({text})" if float(a) < 0 else text
    if not numbers:
        return se.ccode(expr)
    placeholders = {a: se.Symbol(f"LCGNUM{k}X") for k, a in enumerate(numbers)}
    return _PLACEHOLDER.sub(lambda m: table[int(m.group(1))], se.ccode(expr.xreplace(placeholders)))


SYMBOLS = ([se.Symbol(f"y[{i}]") for i in range(10)] + [se.Symbol(f"p[{i}]") for i in range(3)]
           + [se.Symbol(f"x{i}") for i in range(10)] + [se.Symbol("t")])


def random_expression(rng, depth=0):
    r = rng.random()
    if depth > 3 or r < 0.3:
        return rng.choice(SYMBOLS + [se.RealDouble(rng.choice([0.5, -2.25, 9.81, 1e20]))])
    if r < 0.4:
        return rng.choice([se.sin, se.cos, se.exp, se.Abs, se.atan])(random_expression(rng, depth + 1))
    if r < 0.5:
        return se.cos(random_expression(rng, depth + 1) - random_expression(rng, depth + 1))
    if r < 0.7:
        coef = rng.choice([1, 2, -1, -3, se.Rational(1, 2), se.Rational(-3, 7), 0.5, se.pi, se.E])
        return random_expression(rng, depth + 1) * random_expression(rng, depth + 1) * coef
    if r < 0.8:
        exp = rng.choice([2, -1, 3, -2, se.Rational(1, 2), se.Rational(-1, 2), se.Rational(1, 3), SYMBOLS[0]])
        return random_expression(rng, depth + 1) ** exp
    const = rng.choice([0, 1, -2, se.Rational(1, 3), 0.25])
    return random_expression(rng, depth + 1) + random_expression(rng, depth + 1) + const


def test_tree_prints_symengines_c_text():
    rng = random.Random(2)
    checked = 0
    while checked < 3000:
        e = random_expression(rng)
        if any(s in str(e) for s in ("I", "zoo", "nan", "oo")):
            continue
        assert c_expr(e) == symengine_text(e), str(e)
        checked += 1


@pytest.mark.parametrize("expr", [
    se.sign(se.Symbol("y[0]")) * 2, se.Piecewise((se.Symbol("t"), se.Symbol("t") < 1), (2, True)),
    se.Max(se.Symbol("y[0]"), se.Symbol("y[1]"), 2 * se.Symbol("t")), se.Rational(1, 3) * se.Symbol("y[0]") ** 2,
    se.floor(se.Symbol("t")) + se.gamma(se.Symbol("y[1]")), se.exp(-1) * se.Symbol("t")])
def test_special_forms_print_as_symengine_does(expr):
    assert c_expr(expr) == symengine_text(expr)


def test_tree_evaluates_like_symengine():
    # The same tree printed as Fortran reads the same operations: evaluate the C text's tree here.
    y = [0.3, -1.1]
    e = (se.Symbol("y[0]") + 2.5 * se.Symbol("y[1]") ** 2) / (1 - se.Symbol("y[0]")) - se.Rational(1, 3)
    node = lowering.expression(e)

    def ev(n):
        if isinstance(n, ir.Element):
            return y[n.index]
        if isinstance(n, (ir.Number, ir.Integer)):
            return float(n.value)
        if isinstance(n, ir.Ratio):
            return n.num / n.den
        if isinstance(n, ir.Neg):
            return -ev(n.arg)
        if isinstance(n, ir.Power):
            return ev(n.base) ** ev(n.exp)
        ops = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide}
        return ops[n.op](ev(n.left), ev(n.right))
    exact = float(e.xreplace({se.Symbol("y[0]"): y[0], se.Symbol("y[1]"): y[1]}))
    assert abs(ev(node) - exact) <= 1e-15 * abs(exact)
    assert FortranPrinter().doprint(node).count("y(") == 3 and "y[" not in FortranPrinter().doprint(node)


def test_unsupported_expressions_are_refused_by_name():
    with pytest.raises(ModelError, match="zeta"):
        c_expr(se.zeta(se.Symbol("t")))
