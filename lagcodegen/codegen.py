"""C code generation: a :class:`~lagcodegen.scene.Scene` rendered through the jinja2 templates.

Expressions are reduced by common-subexpression elimination (symengine's ``cse``, which
matches sympy's) and printed by symengine's C printer (sympy's C99 printer gives the same
text but costs 90% of the generation time of a 20-link pendulum), with every floating-point
constant printed to 17 significant digits. The symbols of the model are renamed
to array elements before elimination: q_i -> y[i], q_i' -> y[n+i], run-time parameter k ->
p[k]; folded parameters become numbers (printed with 17 significant digits, exact doubles).
"""

from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import jinja2
import symengine as se

from . import __version__
from .errors import ModelError
from .scene import Scene

_INDENT = "    "


def templates_dir() -> Path:
    """Folder holding the jinja2 templates (installed package data, or the source tree)."""
    here = Path(__file__).resolve().parent
    for cand in (here / "templates", here.parent / "templates"):
        if (cand / "c" / "model.c.j2").is_file():
            return cand
    raise FileNotFoundError(f"lagcodegen templates not found next to {here}")


def environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
        undefined=jinja2.StrictUndefined)


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


@dataclass
class GeneratedCode:
    """Generated C sources of one scene: ``files`` maps file name -> text."""

    prefix: str
    model_name: str
    n: int
    state_names: list[str]
    param_names: list[str]
    param_defaults: list[float]
    output_names: list[str]
    jacobian: bool
    nz: int = 0  # quadrature states appended after (q, q'), e.g. reconstructed ignorable coordinates
    files: dict[str, str] = field(default_factory=dict)
    # For build(): extra cffi declarations, extra headers the cffi module includes, and
    # SUNDIALS libraries besides CVODE (e.g. ("ida",)) needed by extra drivers in ``files``.
    cdef_extra: str = ""
    cffi_headers: list[str] = field(default_factory=list)
    sundials_libs: tuple[str, ...] = ()
    # Structural nonzero pattern of df/dy (ny x ny booleans, Scene.jacobian_pattern), or None
    # when unknown (then the band solver probes it numerically); sparse_jacobian: the files
    # <prefix>_sparse.[ch] with <prefix>_jac_sparse are in ``files``.
    jac_pattern: object = None
    sparse_jacobian: bool = False

    @property
    def ny(self) -> int:
        return 2 * self.n + self.nz

    @property
    def np(self) -> int:
        return len(self.param_names)

    @property
    def nout(self) -> int:
        return len(self.output_names)

    @property
    def header_name(self) -> str:
        return f"{self.prefix}.h"

    @property
    def source_name(self) -> str:
        return f"{self.prefix}.c"

    def write(self, directory: str | os.PathLike) -> list[Path]:
        """Write the files into ``directory``, each atomically (temp file + rename)."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        written = []
        for name, text in self.files.items():
            written.append(atomic_write(out / name, text))
        return written


def atomic_write(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` so that readers see the old file or the new one, never half."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _symbol_map(scene: Scene) -> dict:
    eom = scene.eom
    model = eom.model
    n = model.n
    sub = {}
    for i, q in enumerate(model.coords):
        sub[se.Symbol(q.name)] = se.Symbol(f"y[{i}]")
    for i, v in enumerate(model.speeds):
        sub[se.Symbol(v.name)] = se.Symbol(f"y[{n + i}]")
    for k, (name, _) in enumerate(eom.quadratures):
        sub[se.Symbol(name)] = se.Symbol(f"y[{2 * n + k}]")
    for k, name in enumerate(scene.runtime_parameters):
        sub[se.Symbol(name)] = se.Symbol(f"p[{k}]")
    sub.update(scene.substitutions())
    return sub


def mass_matrix_is_diagonal(eom) -> bool:
    """True if every off-diagonal entry of M is structurally zero (the generated solve divides)."""
    n = eom.n
    return n > 1 and all(eom.M_se[i][j] == 0 for i in range(n) for j in range(n) if i != j)


def substituter(scene: Scene):
    """f(expr) renaming the model's symbols to array elements (q_i -> y[i], ...) and folding constants."""
    sub = _symbol_map(scene)

    def c(e):
        return se.sympify(e).xreplace(sub) if sub else se.sympify(e)
    return c


def model_blocks(scene: Scene) -> dict[str, list[tuple[tuple, object]]]:
    """The expressions of each emitted function, language-neutral, in emission order.

    Keys ``rhs``, ``jac`` (if the scene asks for it) and ``out``; each a list of
    (target, symengine expression) with targets ("M", i, j) for the upper triangle of M (the
    code mirrors it), ("F", i), ("ydot", k) (quadrature rates), ("G", i, j) = d r_i / d y_j for
    r = M a - F with a = q'' (the symbols ``a[i]``), ("Z", k, j) = d z'_k / d y_j and ("out", k).
    The C and Fortran backends print the same blocks, so they compute the same numbers.
    """
    eom = scene.eom
    model = eom.model
    n = model.n
    c = substituter(scene)
    mass = [(("M", i, j), c(eom.M_se[i][j])) for i in range(n) for j in range(i, n)]
    blocks = {"rhs": mass + [(("F", i), c(eom.F_se[i])) for i in range(n)]
              + [(("ydot", 2 * n + k), c(rate)) for k, (_, rate) in enumerate(eom.quadratures)]}
    if scene.jacobian:
        a = [se.Symbol(f"a[{i}]") for i in range(n)]
        q = [se.Symbol(s.name) for s in model.coords]
        v = [se.Symbol(s.name) for s in model.speeds]
        acc = [se.Symbol(f"__acc{i}") for i in range(n)]
        r = [sum((eom.M_se[i][j] * acc[j] for j in range(n)), se.Integer(0)) - eom.F_se[i] for i in range(n)]
        asub = dict(zip(acc, a))
        jac = list(mass)
        jac += [(("G", i, j), c(se.diff(r[i], var).xreplace(asub)))
                for j, var in enumerate(q + v) for i in range(n)]
        jac += [(("Z", k, j), c(se.diff(rate, var)))
                for k, (_, rate) in enumerate(eom.quadratures) for j, var in enumerate(q + v)]
        blocks["jac"] = jac
    blocks["out"] = [(("out", k), c(o.expr)) for k, o in enumerate(scene.output_list())]
    return blocks


def _c_target(target: tuple) -> str:
    kind, *idx = target
    if kind == "M":
        i, j = idx
        return f"M[{i}][{j}]" if i == j else f"M[{i}][{j}] = M[{j}][{i}]"
    if kind == "G":  # stored by columns: G[j] is the column d r / d y_j, solved in place
        i, j = idx
        return f"G[{j}][{i}]"
    return kind + "".join(f"[{k}]" for k in idx)


def new_code(scene: Scene) -> GeneratedCode:
    """The GeneratedCode record of ``scene``: layout and names, no files yet."""
    eom = scene.eom
    model = eom.model
    return GeneratedCode(
        prefix=scene.prefix, model_name=model.name, n=model.n,
        state_names=[s.name for s in model.coords] + [s.name for s in model.speeds]
        + [name for name, _ in eom.quadratures],
        param_names=list(scene.runtime_parameters), param_defaults=scene.default_parameters(),
        output_names=[o.name for o in scene.output_list()], jacobian=scene.jacobian, nz=len(eom.quadratures))


def header_context(scene: Scene, code: GeneratedCode) -> dict:
    """The template context shared by ``c/model.h.j2``, ``c/model.c.j2`` and the Fortran module."""
    return dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__,
                model_name=code.model_name, n=code.n, nz=code.nz, ny=code.ny, np=code.np, nout=code.nout,
                state_names=code.state_names, param_names=code.param_names,
                folded=sorted(scene.folded.items()), outputs=code.output_names, jacobian=code.jacobian,
                diagonal=mass_matrix_is_diagonal(scene.eom))


def generate_c(scene: Scene) -> GeneratedCode:
    """Render the C header and source of ``scene`` (functions: rhs, jac if asked, outputs if any)."""
    blocks = model_blocks(scene)

    def emit(name: str) -> str:
        pairs = blocks.get(name, [])
        return emit_block([_c_target(t) for t, _ in pairs], [e for _, e in pairs])

    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx)
    code.files[code.source_name] = env.get_template("c/model.c.j2").render(
        **ctx, rhs=emit("rhs"), jac=emit("jac"), out=emit("out"))
    code.jac_pattern = scene.jacobian_pattern()
    if scene.sparse_jacobian:
        _add_sparse_jacobian(scene, code, substituter(scene), env)
    return code


def _int_rows(values: list[int], per_line: int = 16) -> str:
    rows = [", ".join(str(v) for v in values[k:k + per_line]) for k in range(0, len(values), per_line)]
    return ",\n".join(_INDENT + r for r in rows)


def _add_sparse_jacobian(scene: Scene, code: GeneratedCode, c, env) -> None:
    """Files <prefix>_sparse.h/.c: <prefix>_jac_sparse, the structurally nonzero entries of df/dy
    in compressed-column order (Scene.jacobian_pattern), and the pattern itself.

    When M is structurally diagonal each entry is one expression, -(dr_i/dy_j)/M_ii with
    r = M a - F; otherwise M is factored once and only the columns of dr/dy that have a
    nonzero entry are solved for."""
    eom = scene.eom
    model = eom.model
    n, ny = model.n, code.ny
    pattern = code.jac_pattern
    q = [se.Symbol(s.name) for s in model.coords]
    v = [se.Symbol(s.name) for s in model.speeds]
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    acc = [se.Symbol(f"__acc{i}") for i in range(n)]
    asub = dict(zip(acc, a))
    r = [sum((eom.M_se[i][j] * acc[j] for j in range(n)), se.Integer(0)) - eom.F_se[i] for i in range(n)]
    M = [[c(eom.M_se[i][j]) for j in range(n)] for i in range(n)]
    diagonal = all(M[i][j] == 0 for i in range(n) for j in range(n) if i != j)
    entries = [(i, j) for j in range(ny) for i in range(ny) if pattern[i, j]]
    colptr = [0]
    for j in range(ny):
        colptr.append(colptr[-1] + int(pattern[:, j].sum()))
    targets, exprs, after = [], [], []
    if diagonal:
        for i in range(n):
            targets.append(f"Md[{i}]")
            exprs.append(M[i][i])
    else:
        for i in range(n):
            for j in range(i, n):
                targets.append(f"M[{i}][{j}]" if i == j else f"M[{i}][{j}] = M[{j}][{i}]")
                exprs.append(M[i][j])
    solve_cols = []
    for k, (i, j) in enumerate(entries):
        if i < n:  # dq'_i/dq'_i
            targets.append(f"vals[{k}]")
            exprs.append(se.Integer(1))
        elif i < 2 * n:
            ii = i - n
            d = c(se.diff(r[ii], (q + v)[j]).xreplace(asub)) if j < 2 * n else se.Integer(0)
            if diagonal:
                targets.append(f"vals[{k}]")
                exprs.append(-d / M[ii][ii])
            else:
                if d != 0:
                    targets.append(f"G[{j}][{ii}]")
                    exprs.append(d)
                if j not in solve_cols:
                    solve_cols.append(j)
                after.append(f"{_INDENT}vals[{k}] = -G[{j}][{ii}];")
        else:  # quadrature rates
            targets.append(f"vals[{k}]")
            exprs.append(c(se.diff(eom.quadratures[i - 2 * n][1], (q + v)[j])) if j < 2 * n else se.Integer(0))
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__, model_name=model.name,
               nnz=len(entries), colptr=_int_rows(colptr), rowind=_int_rows([i for i, _ in entries]),
               diagonal=diagonal, block=emit_block(targets, exprs), after="\n".join(after),
               solve_cols=_int_rows(solve_cols), nsolve=len(solve_cols))
    code.files[f"{code.prefix}_sparse.h"] = env.get_template("c/jac_sparse.h.j2").render(**ctx)
    code.files[f"{code.prefix}_sparse.c"] = env.get_template("c/jac_sparse.c.j2").render(**ctx)
    code.cffi_headers.append(f"{code.prefix}_sparse.h")
    code.sparse_jacobian = True


#: Languages the model code can be generated in.
LANGUAGES = ("c", "fortran")


def generate_code(scene: Scene, lang: str = "c") -> GeneratedCode:
    """The model code of ``scene`` in ``lang``: "c" (:func:`generate_c`) or "fortran"
    (:func:`lagcodegen.fortran.generate_fortran`, same functions and header)."""
    if lang == "c":
        return generate_c(scene)
    if lang == "fortran":
        from .fortran import generate_fortran  # fortran.py builds on this module
        return generate_fortran(scene)
    raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
