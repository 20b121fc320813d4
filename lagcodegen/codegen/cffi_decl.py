"""cffi declarations of the generated functions and drivers, one function per kind of generated
code. The structs come from their one declaration (:mod:`.signatures`: every field, so that cffi
checks each layout against the compiled header); the functions are the headers' prototypes. A
runtime header written by hand (lagcodegen/runtime/) is its own declaration: cffi reads its text
(:func:`header_cdef`) rather than a copy of it."""

from __future__ import annotations

import re

from ..runtime import source as runtime_source
from .record import GeneratedCode
from .signatures import (DAE_TABLE, DRIVERS, MODEL_TABLE, TAYLOR_TABLE, c_signature, cffi_struct)

#: A C comment (block or line).
_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.DOTALL)
#: A preprocessor directive: a line whose first non-blank character is #, with the lines it
#: continues onto (a backslash before the line end).
_DIRECTIVE = re.compile(r"^[ \t]*#(?:[^\n]*\\\n)*[^\n]*$", re.MULTILINE)


def strip_directives(text: str) -> str:
    """The C declarations ``text`` (a header) as cffi's ``cdef`` takes them: without comments
    (each one a space, so that a comment that opens on a directive's line goes with it) and
    without preprocessor directives (``#include``, the include guard, ``#define`` s, continued
    over lines or not), the declarations themselves as they are."""
    return _DIRECTIVE.sub("", _COMMENT.sub(" ", text))


def header_cdef(name: str) -> str:
    """The declarations of the runtime header ``name`` (lagcodegen/runtime/, e.g.
    ``"lcg_cvsens.h"``) for cffi (:func:`strip_directives`): its structs, typedefs and prototypes,
    written once, in the header. The types it uses from the headers it includes come first in the
    module's cdef."""
    return strip_directives(runtime_source(name))

#: The Python function the drivers call back while a run is long (progress, Ctrl-C): one per module.
POLL_CDEF = 'extern "Python" int lcg_poll(void *data, long done, long total);'


def driver_cdef(name: str) -> str:
    """The structs of the driver ``name`` (:data:`~.signatures.DRIVERS`), as cffi declarations."""
    return "\n".join(cffi_struct(s) for s in DRIVERS[name].structs)


#: The function table of a compiled model (lcg_model.h).
MODEL_TABLE_CDEF = cffi_struct(MODEL_TABLE)
#: The function table of a compiled constrained model (lcg_dae_model.h) and the events record of
#: its drivers.
DAE_TABLE_CDEF = cffi_struct(DAE_TABLE) + "\n" + driver_cdef("dae")


def constrained_runtime_cdef() -> str:
    """The constrained drivers of the runtime: the index-1 CVODE driver (lcg_cvc.h) with the
    initial state in one call, the GGL IDA driver (lcg_ida.h), their ensembles."""
    return "\n".join([DAE_TABLE_CDEF, driver_cdef("cvc"), header_cdef("lcg_cvc.h"), driver_cdef("ida"),
                      header_cdef("lcg_ida.h")])


def runtime_cdef() -> str:
    """The model-independent runtime module: the model table, the CVODE driver taking it
    (lcg_cvode.h: its runs with events and inputs, its ensembles, the batch of outputs), the
    constrained drivers (:func:`constrained_runtime_cdef`, whose events record the CVODE driver's
    runs with events use too) and the poll callback."""
    return "\n".join([MODEL_TABLE_CDEF, driver_cdef("inputs"), driver_cdef("cvode"), constrained_runtime_cdef(),
                      header_cdef("lcg_cvode.h"), POLL_CDEF])


def model_cdef(code: GeneratedCode, native: bool) -> str:
    """The model functions of ``code`` (:data:`~.signatures.MODEL_FUNCTIONS`, the header's own
    signatures) for a module of its own (code with further drivers, or built without SUNDIALS);
    with ``native``, the poll callback of its drivers."""
    p = code.prefix
    names = ["rhs"] + ["jac"] * code.jacobian + ["outputs"] * bool(code.nout)
    names += ["jac_sparse"] * bool(getattr(code, "sparse_jacobian", False))
    lines = [c_signature(name, p) + ";" for name in names]
    if native:
        lines.append(POLL_CDEF)
    return "\n".join(lines)


#: The table of a model's Taylor jet (lcg_taylor_model.h, templates/taylor/lcg_taylor_model.h.j2).
TAYLOR_TABLE_CDEF = "#define LCG_TAYLOR_ABI ...\n#define LCG_TAYLOR_ORDER_MAX ...\n" + cffi_struct(TAYLOR_TABLE)


def taylor_runtime_cdef() -> str:
    """The model-independent Taylor runtime module: the jet table, the Taylor driver taking it
    (lcg_taylor.h: its runs, the jet, its ensembles) and the poll callback."""
    return "\n".join([TAYLOR_TABLE_CDEF, driver_cdef("taylor"), header_cdef("lcg_taylor.h"), POLL_CDEF])
