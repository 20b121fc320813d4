"""Fortran 2008 code generation: the C backend's functions as a module with C bindings.

:func:`generate_fortran` renders a :class:`~lagcodegen.scene.Scene` into ``<prefix>.f90``
(module ``<prefix>_mod``) and ``<prefix>.h``, the C backend's header, unchanged. Every
function is ``bind(C, name="<prefix>_...")`` with exactly the C signature, so C programs,
the native CVODE driver and the cffi module of :func:`lagcodegen.build` call it exactly like
the C version, and :func:`lagcodegen.build` compiles the ``.f90`` with gfortran.

The arithmetic is the C backend's, operation for operation. The expressions go through the
same symbol renaming (:func:`lagcodegen.codegen._symbol_map`: ``y[i]``, ``p[k]``, the
Jacobian's ``a[i]``), the same common-subexpression elimination (symengine ``cse``) and the
C backend's own expression printer (:func:`lagcodegen.codegen.c_expr`); the C text of each
expression is then parsed and printed as Fortran with the same evaluation tree: ``y[i]`` ->
``y(i+1)``, ``a[i]`` -> ``ydot(N+i+1)``, ``pow(a, b)`` -> ``a**b`` (gfortran calls the same
``pow``, and turns ``x**2.0d0`` into ``x*x`` as gcc does with ``pow(x, 2)``), every number a
double-precision literal with 17 significant digits (``0.69999999999999996d0``; integers
too, so no integer division can arise), ``fabs`` -> ``abs``, C's boolean arithmetic and ``?:`` -> ``merge``,
``==``/``!=`` on reals -> ``<=``/``>=`` tests (same result, NaN included), C99 functions
without a Fortran intrinsic (``cbrt``, ``expm1``, ...) called from libm through
``bind(C)`` interfaces. The solve of M q'' = F (Cholesky, LU with partial pivoting as
fallback; singular -> 1, non-finite -> 2) and the Jacobian reusing one factorization are
written out in the template as in the C one. With gcc and gfortran at the same optimization
level the results are bit-identical to the C backend's where neither compiler contracts
a*b + c into fused multiply-adds (x86-64 without -march; elsewhere use -ffp-contract=off).

Constrained systems: :func:`generate_constrained_fortran_source` renders ``<prefix>_dae.f90``
(module ``<prefix>_dae_mod``, templates/fortran/dae.f90.j2), every function of the C
backend's ``<prefix>_dae.c`` (augmented-system solve with its dense LU, index-1 right-hand
side, residuals, projection, outputs, roots, GGL residual and Jacobian) with the C
signatures and return codes, from the expression blocks the C path prints
(:func:`lagcodegen.formulation.constrained.constrained_blocks`) and with the loops of the C
template written out in the same order. Arguments C callers may pass as NULL (``lam``,
``err``) or that may alias (``y`` and ``ynew`` of ``_project``) are ``type(c_ptr)`` values.
:func:`lagcodegen.compile_constrained` (``lang="fortran"``) builds them behind the same
native CVODE and IDA drivers.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import symengine as se

from ..errors import ModelError
from ..formulation.kernels import Block, model_blocks
from ..formulation.scene import Scene
from .c import c_expr
from .record import GeneratedCode, header_context, new_code
from .templates import environment

_INDENT = "  "
#: Longest public Fortran name is <prefix>_err_singular_mass; Fortran names have <= 63 characters.
MAX_PREFIX = 63 - len("_err_singular_mass")
#: Fortran 2008 allows 255 continuation lines per statement; longer sums are split before that.
_MAX_CONTINUATIONS = 200
#: Code lines are wrapped at this column (free form allows 132).
_LINE = 100

# ----------------------------------------------------------------------------- C -> Fortran
_TOKEN = re.compile(r"""\s*(?:
      (?P<num>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)(?P<suffix>[A-Za-z_]\w*)?
    | (?P<id>[A-Za-z_]\w*)
    | (?P<op>&&|\|\||==|!=|<=|>=|[-+*/()\[\],?:<>!])
    )""", re.X)

#: C99 <math.h> constants (the literal texts of glibc's macros: the same doubles as in C).
_C_CONSTANTS = {
    "M_E": "2.7182818284590452354", "M_LOG2E": "1.4426950408889634074", "M_LOG10E": "0.43429448190325182765",
    "M_LN2": "0.69314718055994530942", "M_LN10": "2.30258509299404568402", "M_PI": "3.14159265358979323846",
    "M_PI_2": "1.57079632679489661923", "M_PI_4": "0.78539816339744830962", "M_1_PI": "0.31830988618379067154",
    "M_2_PI": "0.63661977236758134308", "M_2_SQRTPI": "1.12837916709551257390",
    "M_SQRT2": "1.41421356237309504880", "M_SQRT1_2": "0.70710678118654752440",
}
#: C math functions with a Fortran 2008 intrinsic of the same meaning.
_INTRINSICS = {name: name for name in ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh",
                                       "tanh", "asinh", "acosh", "atanh", "exp", "log", "log10", "sqrt", "erf",
                                       "erfc", "hypot")}
_INTRINSICS.update(fabs="abs", fmax="max", fmin="min", tgamma="gamma", lgamma="log_gamma", copysign="sign")
#: C99 functions without a Fortran intrinsic: called from libm through a bind(C) interface
#: (name -> number of arguments).
_LIBM = {"cbrt": 1, "expm1": 1, "log1p": 1, "exp2": 1, "log2": 1, "fmod": 2, "trunc": 1, "round": 1,
         "floor": 1, "ceil": 1}


def fortran_real(value: float) -> str:
    """A double-precision Fortran literal of ``value`` with 17 significant digits."""
    text = f"{float(value):.17g}"
    if not math.isfinite(float(value)):
        raise ModelError(f"non-finite constant {value} in generated code")
    mantissa, _, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}d{exponent or '0'}"


def fortran_name(name: str, renames: dict[str, tuple[str, int]] | None = None) -> str:
    """The Fortran spelling of a C-named array element: ``y[3]`` -> ``y(4)``; with ``renames``
    ``{"a": ("ydot", 2)}``, ``a[0]`` -> ``ydot(3)``. Other names are unchanged."""
    m = re.fullmatch(r"([A-Za-z_]\w*)\[(\d+)\]", name)
    if not m:
        return name
    array, offset = (renames or {}).get(m.group(1), (m.group(1), 0))
    return f"{array}({int(m.group(2)) + offset + 1})"


class _CParser:
    """Parser of the C expressions the C backend prints (C99 operators, calls, ``a[i]``)."""

    def __init__(self, text: str):
        self.text = text
        self.tokens = []
        pos = 0
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if m is None or m.end() == pos:
                if text[pos:].strip() == "":
                    break
                raise ModelError(f"cannot translate C expression to Fortran (at {text[pos:pos + 20]!r}): {text}")
            if m.group("suffix"):
                raise ModelError(f"cannot translate C number {m.group(0).strip()!r} to Fortran: {text}")
            kind = "num" if m.group("num") else "id" if m.group("id") else "op"
            self.tokens.append((kind, m.group(kind)))
            pos = m.end()
        self.i = 0

    def parse(self):
        node = self.ternary()
        if self.i != len(self.tokens):
            raise self.error()
        return node

    def error(self):
        near = " ".join(v for _, v in self.tokens[self.i:self.i + 5])
        return ModelError(f"cannot translate C expression to Fortran (near {near!r}): {self.text}")

    def peek(self):
        return self.tokens[self.i][1] if self.i < len(self.tokens) else None

    def take(self, value=None):
        if self.i >= len(self.tokens) or (value is not None and self.tokens[self.i][1] != value):
            raise self.error()
        self.i += 1
        return self.tokens[self.i - 1]

    def ternary(self):
        cond = self.binary(0)
        if self.peek() == "?":
            self.take("?")
            a = self.ternary()
            self.take(":")
            return ("?", cond, a, self.ternary())
        return cond

    _LEVELS = (("||",), ("&&",), ("==", "!="), ("<", ">", "<=", ">="), ("+", "-"), ("*", "/"))

    def binary(self, level):
        if level == len(self._LEVELS):
            return self.unary()
        node = self.binary(level + 1)
        while self.peek() in self._LEVELS[level]:
            op = self.take()[1]
            node = ("bin", op, node, self.binary(level + 1))
        return node

    def unary(self):
        if self.peek() in ("-", "+", "!"):
            op = self.take()[1]
            return ("un", op, self.unary())
        return self.primary()

    def primary(self):
        kind, value = self.take()
        if kind == "num":
            return ("num", value)
        if kind == "id":
            if self.peek() == "(":
                self.take("(")
                args = []
                if self.peek() != ")":
                    args.append(self.ternary())
                    while self.peek() == ",":
                        self.take(",")
                        args.append(self.ternary())
                self.take(")")
                return ("call", value, args)
            if self.peek() == "[":
                self.take("[")
                kind, index = self.take()
                if kind != "num" or not index.isdigit():
                    raise self.error()
                self.take("]")
                return ("idx", value, int(index))
            return ("id", value)
        if value == "(":
            node = self.ternary()
            self.take(")")
            return node
        self.i -= 1
        raise self.error()


_ATOM, _POW, _MUL, _NEG, _ADD, _REL, _NOT, _AND, _OR = 9, 8, 7, 6, 5, 4, 3, 2, 1
_LOGICAL_OPS = ("<", ">", "<=", ">=", "==", "!=", "&&", "||")


class _FortranWriter:
    """Fortran text of parsed C expressions, keeping C's evaluation tree.

    ``names``: plain identifiers allowed (CSE temporaries, ``t``); ``renames``: arrays printed
    under another name and offset. Calls of libm functions without a Fortran intrinsic are
    recorded in ``libm``.
    """

    def __init__(self, names, renames=None):
        self.names = set(names)
        self.renames = dict(renames or {})
        self.libm: set[str] = set()

    @staticmethod
    def paren(text_prec, minimum):
        text, prec = text_prec
        return text if prec >= minimum else f"({text})"

    def number(self, node):
        kind = node[0]
        if kind == "num":
            return fortran_real(float(node[1])), _ATOM
        if kind == "id":
            name = node[1]
            if name in _C_CONSTANTS:
                return fortran_real(float(_C_CONSTANTS[name])), _ATOM
            if name not in self.names:
                raise ModelError(f"cannot translate identifier {name!r} to Fortran")
            return name, _ATOM
        if kind == "idx":
            return fortran_name(f"{node[1]}[{node[2]}]", self.renames), _ATOM
        if kind == "call":
            return self.call(node[1], node[2])
        if kind == "?":
            return f"merge({self.number(node[2])[0]}, {self.number(node[3])[0]}, {self.logical(node[1])[0]})", _ATOM
        if kind == "un":
            op, arg = node[1], node[2]
            if op == "!":
                return f"merge(1.0d0, 0.0d0, {self.logical(node)[0]})", _ATOM
            if op == "+":
                return self.number(arg)
            return "-" + self.paren(self.number(arg), _MUL), _NEG
        op, left, right = node[1], node[2], node[3]
        if op in _LOGICAL_OPS:
            return f"merge(1.0d0, 0.0d0, {self.logical(node)[0]})", _ATOM
        if op in ("+", "-"):
            return f"{self.paren(self.number(left), _ADD)} {op} {self.paren(self.number(right), _MUL)}", _ADD
        # * and /: a negated left operand is hoisted (-a*b is -(a*b) in Fortran: the same
        # double, as rounding is symmetric); the right operand keeps C's grouping.
        ltext, lprec = self.number(left)
        rtext = self.paren(self.number(right), _POW)
        if lprec == _NEG:
            return f"{ltext}{op}{rtext}", _NEG
        return f"{self.paren((ltext, lprec), _MUL)}{op}{rtext}", _MUL

    def call(self, name, args):
        texts = [self.number(a)[0] for a in args]
        if name == "pow" and len(args) == 2:
            base = self.paren(self.number(args[0]), _ATOM)
            return f"{base}**{self.paren(self.number(args[1]), _ATOM)}", _POW
        if name in _INTRINSICS:
            return f"{_INTRINSICS[name]}({', '.join(texts)})", _ATOM
        if name in _LIBM and len(args) == _LIBM[name]:
            self.libm.add(name)
            return f"libm_{name}({', '.join(texts)})", _ATOM
        raise ModelError(f"the C function {name!r} has no Fortran translation")

    def logical(self, node):
        if node[0] == "un" and node[1] == "!":
            return f".not. {self.paren(self.logical(node[2]), _ATOM)}", _NOT
        if node[0] != "bin" or node[1] not in _LOGICAL_OPS:
            x = self.number(node)[0]  # C truth of a number: x != 0 (NaN is true)
            return f"(.not. ({x} <= 0.0d0 .and. {x} >= 0.0d0))", _ATOM
        op, left, right = node[1], node[2], node[3]
        if op in ("&&", "||"):
            prec = _AND if op == "&&" else _OR
            word = ".and." if op == "&&" else ".or."
            return (f"{self.paren(self.logical(left), prec)} {word} "
                    f"{self.paren(self.logical(right), prec + 1)}"), prec
        a = self.paren(self.number(left), _ADD)
        b = self.paren(self.number(right), _ADD)
        if op == "==":  # no equality test on reals (gfortran -Wcompare-reals); NaN compares false
            return f"({a} <= {b} .and. {a} >= {b})", _ATOM
        if op == "!=":
            return f"(.not. ({a} <= {b} .and. {a} >= {b}))", _ATOM
        return f"{a} {op} {b}", _REL


def _chain(node, ops):
    """Operands of the left-associative chain ``((a op b) op c) ...`` rooted at ``node``,
    as [(None, a), (op, b), (op, c), ...]."""
    items = []
    while node[0] == "bin" and node[1] in ops:
        items.append((node[1], node[3]))
        node = node[2]
    items.append((None, node))
    return items[::-1]


def _statements(writer: _FortranWriter, target: str, node) -> list[str]:
    """``target = <node>``; a sum (or product) too long for one statement becomes running
    partial results in the same order, ``target = a + b``, ``target = target + c``, ... (the
    same additions as the single C statement)."""
    text = writer.number(node)[0]
    if len(text) < _MAX_CONTINUATIONS * (_LINE - 20):
        return [f"{target} = {text}"]
    for ops in (("+", "-"), ("*", "/")):
        items = _chain(node, ops)
        if len(items) > 1:
            break
    else:
        raise ModelError(f"an expression for {target} is too long for one Fortran statement")
    lines, acc, size = [], None, 0
    for op, operand in items:
        part = writer.number(operand)
        if acc is not None and size + len(part[0]) > (_MAX_CONTINUATIONS // 2) * (_LINE - 20):
            lines.append(f"{target} = {acc}")
            acc, size = target, len(target)
        if acc is None:
            acc = part[0] if ops[0] == "+" else writer.paren(part, _MUL)
        else:
            acc = f"{acc} {op} {writer.paren(part, _MUL)}" if ops[0] == "+" else f"{acc}{op}{writer.paren(part, _POW)}"
        size += len(part[0]) + 3
    lines.append(f"{target} = {acc}")
    return lines


def _wrap(line: str, pad: str) -> list[str]:
    """Free-form continuation lines (``&``) of at most _LINE columns, split between tokens."""
    out, first = [], True
    while True:
        lead = pad if first else pad + "    "
        room = _LINE - len(lead) - 2
        if len(line) <= room + 2:
            out.append(lead + line)
            return out
        cut = -1
        # Split after a space (between terms) if one is near the end, else after a comma,
        # a lone * or /, or "(".
        for allowed in (" ", " ,*/("):
            for k in range(room, room // 2 if allowed == " " else 0, -1):
                c, nxt, prev = line[k - 1], line[k], line[k - 2] if k >= 2 else ""
                if c in allowed and (c not in "*/" or (nxt not in "*=/" and prev not in "*/")):
                    cut = k
                    break
            if cut > 0:
                break
        if cut <= 0:
            raise ModelError(f"cannot wrap Fortran line: {line[:80]}...")
        out.append(lead + line[:cut].rstrip() + " &")
        line = line[cut:].lstrip()
        first = False


@dataclass
class FortranBlock:
    """Declarations, statements, the dummy arguments the statements do not reference, and the
    libm functions they call."""

    decls: str
    code: str
    unused: str  # associate list, e.g. "unused_t => t, unused_p => p(1:0)"; "" if all are used
    libm: tuple[str, ...] = ()


def emit_fortran_block(targets: list[str], exprs: list, after=(), dummies: tuple[str, ...] = (),
                       optional: tuple[str, ...] = (), renames: dict[str, tuple[str, int]] | None = None,
                       indent: int = 2, what: str = "expression", scalars: tuple[str, ...] = ("t",),
                       defs=()) -> FortranBlock:
    """Fortran statements assigning ``exprs`` to ``targets`` after common-subexpression elimination.

    ``exprs`` are in the C backend's symbols (``y[i]``, ``p[k]``, ``t``); the elimination and
    the printed expressions are those of :func:`lagcodegen.codegen.emit_block`, translated.
    ``after``: statements appended verbatim (e.g. mirrored mass-matrix entries).
    ``dummies``: the dummy arguments the statements may reference (any other free symbol is
    an error); those of ``optional`` they do not reference are listed in ``unused`` for a
    no-op ``associate`` (gfortran -Wunused-dummy-argument). ``scalars``: the dummies that are
    scalars (referenced by name, e.g. ``t``, ``cj``) rather than arrays.
    """
    pad = _INDENT * indent
    used: set[str] = set()
    lines: list[str] = []
    temps: list[str] = []
    libm: set[str] = set()
    if exprs:
        repl, reduced = se.cse(list(exprs))
        repl = list(defs) + list(repl)  # a rigid-body tree's program first (kernels.tree_rhs)
        temps = [str(sym) for sym, _ in repl]
        local = set(temps)
        writer = _FortranWriter(local | set(scalars), renames)
        pairs = [(str(sym), e) for sym, e in repl] + list(zip(targets, reduced))
        for target, expr in pairs:
            for s in se.sympify(expr).free_symbols:
                if s.name in local:
                    continue
                owner = fortran_name(s.name, renames).split("(")[0]
                if owner not in dummies:
                    raise ModelError(f"{what}: symbol {s.name!r} is neither a coordinate, a velocity, a "
                                     "parameter nor the time t; it cannot be emitted")
                used.add(owner)
            text = c_expr(expr)
            try:
                node = _CParser(text).parse()
                statements = _statements(writer, target, node)
            except ModelError as exc:
                raise ModelError(f"{what}: {exc}") from None
            for statement in statements:
                lines += _wrap(statement, pad)
        libm = writer.libm
    lines += [pad + line for line in after]
    decls = [f"{pad}real(c_double) :: {', '.join(temps[k:k + 10])}" for k in range(0, len(temps), 10)]
    unused = ", ".join(f"unused_{d} => {d}" if d in scalars else f"unused_{d} => {d}(1:0)"
                       for d in optional if d not in used)
    return FortranBlock("\n".join(decls), "\n".join(lines), unused, tuple(sorted(libm)))


def check_prefix(prefix: str, suffix: str = "_err_singular_mass") -> None:
    """Fortran names start with a letter and have at most 63 characters (``suffix``: the longest
    public name's, after the prefix)."""
    longest = 63 - len(suffix)
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", prefix) or len(prefix) > longest:
        raise ModelError(f"prefix {prefix!r} cannot name a Fortran module: it must start with a letter and have "
                         f"at most {longest} characters (letters, digits, underscores)")


def generate_fortran(scene: Scene) -> GeneratedCode:
    """Render ``<prefix>.f90`` (module ``<prefix>_mod``) and the C header ``<prefix>.h`` of ``scene``.

    The functions are those of :func:`lagcodegen.generate_c` (rhs; jac if the scene asks for
    the Jacobian; outputs if it has any), bound to the same C names and signatures, computed
    from the same expression blocks (:func:`lagcodegen.formulation.kernels.model_blocks`).
    The Jacobian is always the expanded form (``model_blocks``' symbolic dr/dy, code growing
    like n^3): ``Scene.jacobian_form`` ("tangent", or "auto" above
    :data:`~lagcodegen.formulation.scene.EXPANDED_JACOBIAN_MAX_N` coordinates) chooses only the
    C backend's form.
    """
    check_prefix(scene.prefix)
    n = scene.eom.n
    blocks = model_blocks(scene)

    rhs = print_block(blocks["rhs"], f"{scene.prefix}_rhs", ("t", "y", "p"), ("t", "p"))
    jac = None
    if scene.jacobian:  # accelerations a = q'' (C: a = ydot + N), printed as ydot(N+1:2N)
        jac = print_block(blocks["jac"], f"{scene.prefix}_jac", ("t", "y", "ydot", "p"), ("t", "y", "ydot", "p"),
                          renames={"a": ("ydot", n)})
    out = print_block(blocks["out"], f"{scene.prefix}_outputs", ("t", "y", "p"), ("t", "y", "p"))

    code = new_code(scene)
    ctx = header_context(scene, code)
    env = environment()
    code.files[code.header_name] = env.get_template("c/model.h.j2").render(**ctx)
    libm = sorted(set(rhs.libm) | set(jac.libm if jac else ()) | set(out.libm))
    code.files[f"{code.prefix}.f90"] = env.get_template("fortran/model.f90.j2").render(
        **ctx, rhs=rhs, jac=jac, out=out, libm=[(name, _LIBM[name]) for name in libm])
    return code


# ----------------------------------------------------------------------------- constrained systems
#: Longest public name of the constrained module, after the prefix.
DAE_SUFFIX = "_dae_err_projection"


def _fortran_target(target: tuple) -> tuple[str, str | None]:
    """The Fortran spelling of a target of :class:`lagcodegen.formulation.kernels.Block`
    (0-based C indices -> 1-based; ``jac`` is (row, column)), and the mirrored assignment of
    an off-diagonal mass-matrix entry."""
    name, *ix = target
    text = f"{name}({', '.join(str(k + 1) for k in ix)})"
    if name == "M" and ix[0] != ix[1]:
        return text, f"M({ix[1] + 1}, {ix[0] + 1}) = {text}"
    return text, None


def print_block(block: Block, what: str, dummies: tuple[str, ...], optional: tuple[str, ...] = (),
                       renames: dict | None = None, scalars: tuple[str, ...] = ("t",)) -> FortranBlock:
    targets, mirror = [], []
    for target in block.targets:
        text, after = _fortran_target(target)
        targets.append(text)
        if after:
            mirror.append(after)
    exprs, defs = block.exprs, ()
    if block.defs:  # a rigid-body tree's temporaries __mb<k>, renamed mb<k> (Fortran names start with a letter)
        ren = {sym: se.Symbol(sym.name[2:]) for sym, _ in block.defs}
        defs = [(ren[sym], se.sympify(e).xreplace(ren)) for sym, e in block.defs]
        exprs = [se.sympify(e).xreplace(ren) for e in exprs]
    return emit_fortran_block(targets, exprs, mirror, dummies=dummies, optional=optional, renames=renames,
                              what=what, scalars=scalars, defs=defs)


def generate(scene: Scene) -> GeneratedCode:
    """The language interface of :mod:`lagcodegen.codegen`: :func:`generate_fortran`."""
    return generate_fortran(scene)


def constrained_source(cb, ctx: dict) -> dict[str, str]:
    """``<prefix>_dae.f90``: :func:`generate_constrained_fortran_source`."""
    return {f"{ctx['prefix']}_dae.f90": generate_constrained_fortran_source(cb, ctx)}


def generate_constrained_fortran_source(cb, ctx: dict) -> str:
    """``<prefix>_dae.f90`` (module ``<prefix>_dae_mod``): the functions of ``c/dae.c.j2`` for
    the expression blocks ``cb`` (:func:`lagcodegen.formulation.constrained.constrained_blocks`),
    bound to the same C names and signatures and evaluating the same operations.

    ``ctx``: the template context of ``c/dae.h.j2`` (sizes, names, flags).
    """
    prefix = ctx["prefix"]
    check_prefix(prefix, DAE_SUFFIX)
    b = cb.blocks
    plain = ("t", "y", "p")
    blocks = dict(
        mf=print_block(b["mf"], f"{prefix} mass matrix and forces", plain, plain),
        con=print_block(b["con"], f"{prefix} constraints", plain, plain),
        gam=print_block(b["gam"], f"{prefix} gamma", plain, plain),
        out=print_block(b["out"], f"{prefix}_coutputs", (*plain, "lamv"), plain,
                               renames={"lam": ("lamv", 0)}),
        roots=print_block(b["roots"], f"{prefix}_roots", (*plain, "lamv"), plain,
                                 renames={"lam": ("lamv", 0)}),
        ggl_res=print_block(b["ggl_res"], f"{prefix}_ggl_res", ("t", "yy", "yp", "p"),
                                   ("t", "yy", "yp", "p"), renames={"y": ("yy", 0)}),
        ggl_jac=print_block(b["ggl_jac"], f"{prefix}_ggl_jac", ("t", "cj", "yy", "yp", "p"),
                                   ("t", "cj", "yy", "yp", "p"), renames={"y": ("yy", 0)}, scalars=("t", "cj")),
    )
    libm = sorted(set().union(*(blk.libm for blk in blocks.values())))
    text = environment().get_template("fortran/dae.f90.j2").render(
        **ctx, blk=blocks, libm=[(name, _LIBM[name]) for name in libm])
    lines = []
    for line in text.split("\n"):  # long associate lists of unused arguments
        stripped = line.lstrip()
        if len(line) > _LINE and "!" not in line:
            lines += _wrap(stripped, line[:len(line) - len(stripped)])
        else:
            lines.append(line)
    return "\n".join(lines)
