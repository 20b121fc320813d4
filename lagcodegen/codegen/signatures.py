"""The signatures of the generated model functions, once: the C header's prototypes, the
definitions in the C sources, the cffi declarations and the Fortran ``bind(C)`` interfaces are
all printed from :data:`MODEL_FUNCTIONS` (templates call :func:`c_signature` and
:func:`fortran_signature` as jinja2 globals)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Arg:
    """One argument: its name, C type, and for arrays the Fortran extent (None: a scalar by
    value); ``out`` marks arrays the function writes."""

    name: str
    ctype: str
    extent: str | None = None
    out: bool = False

    def c(self) -> str:
        return f"{self.ctype} {self.name}" if not self.ctype.endswith("*") else f"{self.ctype}{self.name}"

    def fortran(self) -> str:
        if self.extent is None:
            kind = "integer(c_int)" if self.ctype == "int" else "real(c_double)"
            return f"{kind}, value, intent(in) :: {self.name}"
        return f"real(c_double), intent({'out' if self.out else 'in'}) :: {self.name}({self.extent})"


@dataclass(frozen=True)
class Signature:
    """A generated function ``int <prefix>_<name>(args)`` returning 0 or an error code."""

    name: str
    args: tuple[Arg, ...]

    def c(self, prefix: str) -> str:
        return f"int {prefix}_{self.name}({', '.join(a.c() for a in self.args)})"

    def fortran(self, prefix: str) -> str:
        names = ", ".join(a.name for a in self.args)
        lines = [f"  recursive integer(c_int) function {prefix}_{self.name}({names}) &",
                 f'      bind(C, name="{prefix}_{self.name}") result(rc)']
        lines += [f"    {a.fortran()}" for a in self.args]
        return "\n".join(lines)


_T = Arg("t", "double")
_Y = Arg("y", "const double *", "ny")
_YDOT_IN = Arg("ydot", "const double *", "ny")
_P = Arg("p", "const double *", "*")

#: The model functions every language emits (:mod:`lagcodegen.codegen.c`,
#: :mod:`lagcodegen.codegen.fortran`).
MODEL_FUNCTIONS = {sig.name: sig for sig in (
    Signature("rhs", (_T, _Y, _P, Arg("ydot", "double *", "ny", out=True))),
    Signature("jac", (_T, _Y, _YDOT_IN, _P, Arg("jac", "double *", "ny, ny", out=True))),
    Signature("outputs", (_T, _Y, _P, Arg("out", "double *", "nout", out=True))),
    Signature("jac_sparse", (_T, _Y, _YDOT_IN, _P, Arg("vals", "double *", "nnz", out=True))),
)}


def c_signature(name: str, prefix: str) -> str:
    """``int <prefix>_<name>(...)``: the C prototype (add ``;``) or the definition's first line."""
    return MODEL_FUNCTIONS[name].c(prefix)


def fortran_signature(name: str, prefix: str) -> str:
    """The ``bind(C)`` function statement and argument declarations of ``name`` in Fortran."""
    return MODEL_FUNCTIONS[name].fortran(prefix)
