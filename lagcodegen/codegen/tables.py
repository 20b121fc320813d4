"""The function tables of generated code as C: ``<prefix>_table.c`` (lcg_model.h) and, for
constrained code, ``<prefix>_dae_table.c`` (lcg_dae_model.h), through which the
model-independent native drivers (and the impact table of systems with contacts) reach the
model's functions. Rendered here for the build (:func:`lagcodegen.build.table_source`) and for
the bundles of systems with contacts alike."""

from __future__ import annotations

from ..errors import LagcodegenError
from ..version import __version__
from .record import GeneratedCode
from .templates import environment


def model_table(code: GeneratedCode) -> str:
    """The text of ``<prefix>_table.c`` of ``code``."""
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__, model_name=code.model_name,
               jacobian=code.jacobian, outputs=bool(code.nout),
               sparse=bool(getattr(code, "sparse_jacobian", False)), nv=getattr(code, "nv", None))
    return environment().get_template("c/model_table.c.j2").render(**ctx)


def dae_table(code: GeneratedCode) -> str:
    """The text of ``<prefix>_dae_table.c`` of constrained ``code`` (``code.dae``)."""
    if code.dae is None:
        raise LagcodegenError(f"{code.prefix!r} is not constrained code (generate_constrained)")
    ctx = dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__, model_name=code.model_name,
               roots=code.dae.nroot > 0, ggl=code.dae.ggl, ggl_jac=code.dae.ggl_jac)
    return environment().get_template("c/dae_table.c.j2").render(**ctx)
