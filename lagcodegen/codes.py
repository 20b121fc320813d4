"""The result codes of the generated model functions and of the native drivers, with their texts,
declared once: the C ``#define`` s of the runtime (``lcg_codes.h``, :func:`c_header`) are rendered
from this table, and every Python check of a code or flag reads it.

Three kinds of number:

* :class:`ModelCode`: what a generated model function returns (0 or a positive error code; every
  language, every formulation).
* :class:`Flag`: the flags lagcodegen's drivers and ensembles add to their solver's own
  (negative, below the solver's; ``-100 - e`` carries model error ``e``).
* :data:`SOLVER_FLAG_TEXT`: what a negative flag of each solver family means (SUNDIALS' own
  return flags for CVODE and IDA; the Taylor driver's), and :data:`NONFINITE_CAUSES`, the
  solver flags a run ends with when a non-finite value the model computed just before is the
  cause (the drivers then report that value and its time instead).
"""

from __future__ import annotations

import enum

from .version import __version__


class ModelCode(enum.IntEnum):
    """Return codes of the generated model functions (``<PREFIX>_OK``, ... of every header)."""

    OK = 0
    SINGULAR = 1     #: singular mass matrix (constrained: augmented matrix [M A^T; A 0])
    NONFINITE = 2    #: a computed value is not finite
    PROJECTION = 3   #: the Gauss-Newton projection onto the constraints did not converge


#: C names of the model codes: (plain model, lcg_model.h; constrained model, lcg_dae_model.h) and
#: each code's comment.
MODEL_CODE_C = {
    ModelCode.OK: ("LCG_OK", "LCG_DAE_OK", "success"),
    ModelCode.SINGULAR: ("LCG_ERR_SINGULAR_MASS", "LCG_DAE_ERR_SINGULAR",
                         "the mass matrix (constrained: the augmented matrix [M A^T; A 0]) is singular"),
    ModelCode.NONFINITE: ("LCG_ERR_NONFINITE", "LCG_DAE_ERR_NONFINITE", "a computed value is not finite"),
    ModelCode.PROJECTION: (None, "LCG_DAE_ERR_PROJECTION", "the Gauss-Newton projection did not converge"),
}


class Flag(enum.IntEnum):
    """Flags of lagcodegen's drivers and ensembles beside the solver's own (C: ``LCG_FLAG_<name>``)."""

    NOMEM = -20           #: out of memory (the SUNDIALS drivers: creating the solver)
    NOMEM_IDA = -21       #: out of memory creating the IDA solver
    BAD_INPUT = -22       #: bad options, or a model table of another layout
    CANCELLED = -80       #: the cancel flag was set, or the poll callback returned nonzero
    TIMED_OUT = -81       #: the wall-clock limit max_wall was reached
    NOT_RUN = -82         #: an ensemble member never started
    CHUNK_FAILED = -83    #: an ensemble member whose chunk failed on the executor
    REJECTED = -84        #: an ensemble member whose initial state was rejected
    CONTACT_MODE = -85    #: contacts with Coulomb friction: no unique stick/slip/release mode (Painleve)
    MODEL_ERROR = -100    #: -100 - e: the model function returned error e (:func:`model_error_flag`)


#: What each of lagcodegen's flags means (run control and ensembles).
FLAG_TEXT = {
    int(Flag.CANCELLED): "cancelled",
    int(Flag.TIMED_OUT): "the wall-clock limit max_wall was reached",
    int(Flag.NOT_RUN): "not run (the ensemble was cancelled first)",
    int(Flag.CHUNK_FAILED): "its chunk failed on the executor",
    int(Flag.REJECTED): "the initial state was rejected",
    int(Flag.CONTACT_MODE): "no unique contact mode of the contacts with friction (Painleve's paradox)",
}


#: What each flag means, in the C header's comments.
FLAG_DOC = {
    Flag.NOMEM: "out of memory", Flag.NOMEM_IDA: "out of memory creating the IDA solver",
    Flag.BAD_INPUT: "bad options, or a model table of another layout",
    **{Flag(k): v for k, v in FLAG_TEXT.items()},
    Flag.MODEL_ERROR: "LCG_MODEL_ERROR_FLAG(rc): a model function returned error rc",
}


def model_error_flag(code: int) -> int:
    """The driver flag of a run that a model function ended with error ``code``: -100 - code."""
    return int(Flag.MODEL_ERROR) - int(code)


#: The step budget used up (every family: CVODE's and IDA's TOO_MUCH_WORK, the Taylor driver's own).
TOO_MUCH_WORK = -1

_COMMON_TEXT = {
    TOO_MUCH_WORK: "too many steps (max_steps reached); raise max_steps or loosen the tolerances",
    -2: "tolerance too tight for machine precision",
    -3: "error test failed repeatedly or with |h| = hmin",
}
#: What a negative return flag of each solver family means.
SOLVER_FLAG_TEXT = {
    "CVODE": {
        **_COMMON_TEXT,
        -4: "corrector convergence failed repeatedly",
        -8: "the right-hand side failed unrecoverably",
        -9: "the right-hand side failed at the first call",
        -10: "the right-hand side failed repeatedly with recoverable errors (non-finite values)",
        -12: "a root (event) function failed",
        -30: "the projection onto the constraints failed unrecoverably",
        -31: "the projection onto the constraints failed repeatedly",
    },
    "IDA": {
        **_COMMON_TEXT,
        -4: "Newton iteration failed to converge repeatedly",
        -6: "the linear solver setup failed (singular iteration matrix?)",
        -7: "the linear solve failed",
        -8: "the residual failed unrecoverably",
        -9: "the residual failed repeatedly with recoverable errors (non-finite values)",
        -10: "a root (event) function failed",
        -12: "the residual failed at the first call",
        -13: "IDACalcIC: line search failed (no consistent lambda and y' found)",
        -14: "IDACalcIC: the residual failed; no consistent initial values",
    },
    "Taylor": {
        TOO_MUCH_WORK: _COMMON_TEXT[TOO_MUCH_WORK],
        -3: "the step size fell below the resolution of t (is the solution singular there?)",
        int(Flag.NOMEM): "out of memory",
        int(Flag.BAD_INPUT): "bad options",
    },
}
SOLVER_FLAG_TEXT["scikit-sundae"] = SOLVER_FLAG_TEXT["CVODE"]

#: CVODE flags that a non-finite value of the right-hand side just before is the cause of: the
#: error test (-3), corrector convergence (-4), right-hand-side failures (-9 first call, -10
#: repeated recoverable errors, -11 unrecoverable). The native driver (``LCG_CVODE_NONFINITE_CAUSE``)
#: and the scikit-sundae runner then report the value's time and model error NONFINITE.
NONFINITE_CAUSES = {"CVODE": (-3, -4, -9, -10, -11)}


def c_header() -> str:
    """``lcg_codes.h``: the codes above as C ``#define`` s (with the attribution rule of non-finite
    values as a macro), for the runtime's drivers and the model tables' headers."""
    lines = [f"/* lcg_codes.h -- generated by lagcodegen {__version__} from lagcodegen/codes.py.",
             " *",
             " * The return codes of the generated model functions and the flags of the native drivers",
             " * (besides their solver's own). Pure C99; no other dependency. */",
             "#ifndef LCG_CODES_H", "#define LCG_CODES_H", "",
             "/* The model functions' return codes (every model, every language; lcg_model.h). */"]
    lines += [f"#define {plain} {int(code)} /* {text} */" for code, (plain, _dae, text) in MODEL_CODE_C.items() if plain]
    lines += ["", "/* The constrained model functions' return codes (<PREFIX>_DAE_OK, ... of every <prefix>_dae.h). */"]
    lines += [f"#define {dae} {int(code)} /* {text} */" for code, (_plain, dae, text) in MODEL_CODE_C.items()]
    lines += ["", "/* The drivers' flags besides their solver's own. */"]
    lines += [f"#define LCG_FLAG_{flag.name} ({int(flag)}) /* {FLAG_DOC[flag]} */" for flag in Flag]
    lines += ["/* The flag of a run that a model function ended with error code rc. */",
              "#define LCG_MODEL_ERROR_FLAG(rc) (LCG_FLAG_MODEL_ERROR - (rc))", ""]
    for family, flags in NONFINITE_CAUSES.items():
        test = " || ".join(f"(flag) == {f}" for f in flags)
        lines += [f"/* {family} flags that a non-finite value computed just before is the cause of. */",
                  f"#define LCG_{family}_NONFINITE_CAUSE(flag) ({test})", ""]
    lines += ["#endif /* LCG_CODES_H */", ""]
    return "\n".join(lines)
