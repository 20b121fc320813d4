"""How lagcodegen's objects show themselves in a notebook: the HTML and LaTeX of models, derived
equations, compiled models and results, each of bounded size (a 20-link chain's equations show
a few rows, each cut to :data:`MAX_LATEX` characters, and say how many more there are).

The objects' ``_repr_html_`` / ``_repr_latex_`` methods call the functions here (duck-typed:
nothing of the higher stages is imported); :class:`CompiledReprMixin` gives a compiled model
its HTML. One of the lowest stages (beside :mod:`lagcodegen.animation`): sympy and numpy only.
"""

from __future__ import annotations

import functools
import html
import time
from typing import Iterable, Sequence

import numpy as np
import sympy as sp

#: Items of a list shown before "... (n more)".
MAX_ITEMS = 12
#: Equations shown of a system of equations.
MAX_EQUATIONS = 4
#: Characters of one expression's LaTeX (longer: its size is said instead).
MAX_LATEX = 1200
#: Rows of a result's head table (the first ones, then the last).
HEAD_ROWS = 5
#: Columns of a result's head table.
MAX_COLUMNS = 10
#: Expressions up to this many characters are shown trigonometrically simplified (sin^2 + cos^2
#: = 1, cos(a)cos(b) + sin(a)sin(b) = cos(a - b)), within SIMPLIFY_SECONDS per display.
SIMPLIFY_CHARS = 400
SIMPLIFY_SECONDS = 2.0


def esc(x: object) -> str:
    return html.escape(str(x))


def more(items: Sequence, limit: int = MAX_ITEMS) -> list:
    """The first ``limit`` items, then the string ``"... (n more)"`` if some were left out."""
    items = list(items)
    if len(items) <= limit:
        return items
    return items[:limit] + [f"... ({len(items) - limit} more)"]


def joined(items: Iterable, limit: int = MAX_ITEMS) -> str:
    return ", ".join(esc(i) for i in more(list(items), limit)) or "none"


def table(header: Sequence[str], rows: Sequence[Sequence[object]], caption: str = "") -> str:
    """An HTML table (cells escaped)."""
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>" for row in rows)
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def fields(title: str, items: Sequence[tuple[str, str]]) -> str:
    """A titled definition table: each (label, already-escaped HTML value)."""
    rows = "".join(f"<tr><th style='text-align:left'>{esc(k)}</th><td style='text-align:left'>{v}</td></tr>"
                   for k, v in items)
    return f"<div><strong>{esc(title)}</strong><table>{rows}</table></div>"


# ---------------------------------------------------------------------- symbols and expressions
def dotted_names(coords: Sequence[sp.Symbol]) -> dict:
    """LaTeX names of the velocity and acceleration symbols: ``theta_dot`` -> ``\\dot{\\theta}``."""
    names = {}
    for q in coords:
        base = sp.latex(sp.Symbol(q.name))
        names[sp.Symbol(f"{q.name}_dot")] = rf"\dot{{{base}}}"
        names[sp.Symbol(f"{q.name}_ddot")] = rf"\ddot{{{base}}}"
    return names


class Budget:
    """Seconds left for simplification in one display."""

    def __init__(self, seconds: float = SIMPLIFY_SECONDS):
        self.end = time.perf_counter() + seconds

    def simplified(self, expr: sp.Expr, text: str) -> sp.Expr:
        if len(text) > SIMPLIFY_CHARS or time.perf_counter() > self.end:
            return expr
        return sp.trigsimp(expr)


def latex(expr, names: dict, limit: int = MAX_LATEX, budget: Budget | None = None) -> str:
    """LaTeX of a sympy (or symengine) expression with dotted velocity names (short ones
    simplified within ``budget``); an expression whose text is longer than ``limit`` is replaced
    by a note of its size (measured before printing)."""
    text = str(expr)
    if len(text) > limit:
        return rf"\text{{(an expression of {len(text)} characters)}}"
    e = sp.sympify(expr)
    if budget is not None:
        e = budget.simplified(e, text)
    out = sp.latex(e, symbol_names=names)
    if len(out) > limit:
        return rf"\text{{(an expression of {len(text)} characters)}}"
    return out


# ---------------------------------------------------------------------- models
def model_html(model) -> str:
    """A model's name, coordinates, parameters, bodies, energies, forces and outputs."""
    bodies = [f"{type(b).__name__} {b.name} (m = {b.mass})" for b in model.bodies]
    items = [
        ("coordinates", joined(q.name for q in model.coords)),
        ("parameters", joined(f"{s.name} = {v:g}" for s, v in model.params.items())),
        ("points", joined(model.points)),
        ("bodies", joined(bodies)),
        ("gravity", esc(model.gravity_spec[0]) if model.gravity_spec else "none"),
        ("potentials", joined(label for label, _ in model.potential_terms)),
        ("kinetic energy given", joined(label for label, _ in model.kinetic_terms)),
        ("dissipation", joined(label for label, _ in model.dissipation_terms)),
        ("forces", joined([label for label, _, _ in model.cartesian_forces]
                          + [label for label, _, _ in model.generalized_forces])),
        ("outputs", joined(model.outputs)),
    ]
    return fields(f"Model {model.name}: {model.n} coordinate{'s' if model.n != 1 else ''}", items)


def model_latex(model) -> str:
    """The energies a model states directly (T given, V terms) and its coordinates, in LaTeX."""
    names = dotted_names(model.coords)
    q = ", ".join(sp.latex(c) for c in more(model.coords, MAX_ITEMS) if isinstance(c, sp.Basic))
    if model.n > MAX_ITEMS:
        q += rf", \ldots\ \text{{({model.n - MAX_ITEMS} more)}}"
    lines = [rf"\text{{{_tex_text(model.name)}}}:\ q = ({q})"]
    for symbol, terms in (("T", model.kinetic_terms), ("V", model.potential_terms)):
        for label, expr in terms[:MAX_EQUATIONS]:
            lines.append(_labelled(symbol, label, expr, names))
        if len(terms) > MAX_EQUATIONS:
            lines.append(rf"\text{{... ({len(terms) - MAX_EQUATIONS} more {symbol} terms)}}")
    if model.bodies:
        lines.append(rf"\text{{bodies: {_tex_text(', '.join(more([b.name for b in model.bodies])))}}}")
    return "$\\begin{array}{l}" + r" \\ ".join(lines) + r"\end{array}$"


def _labelled(symbol: str, label: str, expr, names) -> str:
    return rf"{symbol}_{{\text{{{_tex_text(label)}}}}} = {latex(expr, names)}"


def _tex_text(s: str) -> str:
    """``s`` safe inside ``\\text{}``."""
    for a, b in (("\\", r"\backslash "), ("_", r"\_"), ("{", r"\{"), ("}", r"\}"), ("#", r"\#"), ("%", r"\%"),
                 ("&", r"\&"), ("$", r"\$"), ("^", r"\^{}"), ("~", r"\~{}")):
        s = s.replace(a, b)
    return s


# ---------------------------------------------------------------------- equations of motion
def eom_rows(eom, limit: int = MAX_EQUATIONS) -> list[str]:
    """LaTeX of the first ``limit`` of Lagrange's equations sum_j M_ij q_j'' = F_i (eq. 3.16),
    the last item ``\\text{... (n more)}`` if some are left out."""
    model = eom.model
    names = dotted_names(model.coords)
    n = model.n
    budget = Budget()
    rows = []
    for i in range(min(n, limit)):
        terms = []
        for j in range(n):
            m = eom.M_se[i][j]
            if m == 0:
                continue
            acc = names[sp.Symbol(f"{model.coords[j].name}_ddot")]
            coef = latex(m, names, budget=budget)
            terms.append(acc if coef == "1" else rf"\left({coef}\right) {acc}")
        lhs = " + ".join(more(terms, MAX_EQUATIONS)) if len(terms) <= MAX_EQUATIONS else \
            " + ".join(terms[:MAX_EQUATIONS]) + rf" + \ldots\ \text{{({len(terms) - MAX_EQUATIONS} more terms)}}"
        rows.append(rf"{lhs or '0'} &= {latex(eom.F_se[i], names, budget=budget)}")
    if n > limit:
        rows.append(rf"&\ \text{{... ({n - limit} more)}}")
    return rows


def eom_latex(eom) -> str:
    """Lagrange's equations M q'' = F, rows truncated (see :func:`eom_rows`)."""
    return "$\\begin{aligned}" + r" \\ ".join(eom_rows(eom)) + r"\end{aligned}$"


def eom_html(eom) -> str:
    """The model's summary and the equations (MathJax in the notebook)."""
    model = eom.model
    body = eom_latex(eom)
    summary = (f"Lagrange's equations of {esc(model.name)} ({model.n} coordinate{'s' if model.n != 1 else ''}, "
               f"derived in {eom.derivation_seconds:.2f} s)")
    return f"<div><strong>{summary}</strong><div>{html.escape(body)}</div></div>"


# ---------------------------------------------------------------------- compiled models
class CompiledReprMixin:
    """``_repr_html_`` of a compiled model: names, sizes, the compiled functions, the cache entry.
    Reads ``code`` (the generated code's record), ``path``, ``cached``, ``native`` and the bound
    ``c_*`` functions of the class it is mixed into."""

    def _repr_html_(self) -> str:
        code = self.code
        functions = [name for name, attr in (("rhs", "c_rhs"), ("jac", "c_jac"), ("jac_sparse", "c_jac_sparse"),
                                             ("outputs", "c_outputs"), ("kkt", "c_kkt"),
                                             ("residuals", "c_residuals"), ("project", "c_project"))
                     if getattr(self, attr, None) is not None]
        defaults = dict(zip(code.param_names, code.param_defaults))
        items = [
            ("sizes", esc(f"n = {code.n} coordinates, {code.ny} states, {len(code.param_names)} run-time "
                          f"parameters, {len(code.output_names)} outputs")),
            ("states", joined(code.state_names)),
            ("run-time parameters", joined(f"{k} = {v:g}" for k, v in defaults.items())),
            ("folded parameters", joined(f"{k} = {v:g}" for k, v in (code.folded or {}).items())),
            ("outputs", joined(code.output_names)),
            ("functions", joined(functions)),
            ("Jacobian", "analytic" if code.jacobian else "difference quotients"),
            ("native driver", "yes" if getattr(self, "native", False) else "no"),
            ("cache entry", esc(f"{getattr(self, 'path', '')}" + (" (reused)" if getattr(self, "cached", False)
                                                                   else " (built now)"))),
        ]
        return fields(f"Compiled model {code.model_name} (prefix {code.prefix})", items)


# ---------------------------------------------------------------------- results
def result_html(res) -> str:
    """A result's head table (first rows, then the last; the first columns) and its statistics."""
    cols = res.columns()
    names = list(cols)
    shown = names[:MAX_COLUMNS]
    n = len(res.t)
    idx = list(range(min(n, HEAD_ROWS)))
    if n > HEAD_ROWS:
        idx.append(n - 1)
    rows = []
    for k, i in enumerate(idx):
        if n > HEAD_ROWS and k == len(idx) - 1:
            rows.append(["..."] * len(shown))
        rows.append([f"{float(cols[c][i]):.6g}" for c in shown])
    caption = f"{n} rows x {len(names)} columns" + (f" (first {len(shown)} shown)" if len(shown) < len(names) else "")
    stats = [(k, esc(v)) for k, v in list(res.stats.items())[:MAX_ITEMS] if np.isscalar(v)]
    title = (f"Result of {res.model_name}: " if getattr(res, "model_name", "") else "Result: ") + \
        f"{'ok' if res.success else 'failed'} ({res.backend} {res.method})".replace(" )", ")")
    items = [("status", esc(f"{res.status} {res.message}".strip())), ("t", esc(f"{res.t[0]:g} .. {res.t[-1]:g}")
                                                                        if n else "empty")]
    return fields(title, items + stats) + table(shown, rows, caption)


def figure_png(fig) -> bytes:
    """The PNG of a matplotlib figure (drawn by Agg at its own size and dpi)."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return buffer.getvalue()


def shown(fig):
    """``fig`` (a matplotlib figure made without pyplot, which no notebook backend knows of)
    given a ``_repr_png_``, so that a notebook cell ending with it draws the figure rather than
    printing ``<Figure size ... with n Axes>``. Where pyplot's inline backend is active its own
    formatter draws it instead (IPython asks the formatters registered by type first): one
    picture either way."""
    fig._repr_png_ = functools.partial(figure_png, fig)
    return fig

