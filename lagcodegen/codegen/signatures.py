"""The interface between generated code, the runtime's C drivers and Python, declared once: the
signatures of the generated model functions (:data:`MODEL_FUNCTIONS`, :data:`DAE_FUNCTIONS`) and
the structs the drivers exchange (options, statistics, ensembles, events, the model tables:
:data:`DRIVERS`, :data:`MODEL_TABLE`, ...). From them come the C header's prototypes and the
Fortran ``bind(C)`` interfaces (templates call :func:`c_signature` and :func:`fortran_signature`
as jinja2 globals), the drivers' generated headers ``lcg_<driver>_types.h`` (:func:`c_header`),
the cffi declarations (:func:`cffi_struct`), the Python pack formats of the options
(:func:`pack_format`) and the keys of Result.stats (:data:`STAT_NAMES`)."""

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


_D = "double"
_CD = "const double *"
_OUT = "double *"

#: The functions of a constrained model (<prefix>_dae.h; the lcg_dae_model table points to them):
#: the augmented system (kkt, eq. 4.5), the index-1 right-hand side (crhs), the natural rate of
#: the Baumgarte parameters, the constraint residuals, the projection onto the constraints, the
#: outputs, the event functions, the GGL residual and its Jacobian.
DAE_FUNCTIONS = {sig.name: sig for sig in (
    Signature("kkt", (_T, _Y, _P, Arg("alpha", _D), Arg("beta", _D), Arg("acc", _OUT, "nq", out=True),
                      Arg("lam", _OUT, "nj", out=True))),
    Signature("crhs", (_T, _Y, _P, Arg("alpha", _D), Arg("beta", _D), Arg("ydot", _OUT, "ny", out=True))),
    Signature("natural_rate", (_T, _Y, _P, Arg("rate", _OUT, "1", out=True))),
    Signature("residuals", (_T, _Y, _P, Arg("g", _OUT, "njh", out=True), Arg("s", _OUT, "nj", out=True))),
    Signature("project", (_T, _Y, _P, Arg("tol", _D), Arg("maxit", "int"), Arg("ynew", _OUT, "ny", out=True),
                          Arg("err", _OUT, "1", out=True))),
    Signature("coutputs", (_T, _Y, Arg("lam", _CD, "nj"), _P, Arg("out", _OUT, "nout", out=True))),
    Signature("roots", (_T, _Y, Arg("lam", _CD, "nj"), _P, Arg("gout", _OUT, "nroot", out=True))),
    Signature("ggl_res", (_T, Arg("yy", _CD, "ng"), Arg("yp", _CD, "ng"), _P, Arg("rr", _OUT, "ng", out=True))),
    Signature("ggl_jac", (_T, Arg("cj", _D), Arg("yy", _CD, "ng"), Arg("yp", _CD, "ng"), _P,
                          Arg("jac", _OUT, "ng, ng", out=True))),
)}


def c_signature(name: str, prefix: str) -> str:
    """``int <prefix>_<name>(...)``: the C prototype (add ``;``) or the definition's first line."""
    return MODEL_FUNCTIONS[name].c(prefix)


def fortran_signature(name: str, prefix: str) -> str:
    """The ``bind(C)`` function statement and argument declarations of ``name`` in Fortran."""
    return MODEL_FUNCTIONS[name].fortran(prefix)


# ------------------------------------------------------------------------------------------------
# The structs the native drivers exchange with Python: options, statistics, ensembles, events.
# Each is declared here once; the C header (lcg_<driver>_types.h, :func:`c_header`), the cffi
# declarations (:func:`cffi_struct`), the Python pack formats of the options that vary between
# runs (:func:`pack_format`) and the keys of Result.stats (:data:`STAT_NAMES`) are derived from it.


@dataclass(frozen=True)
class Field:
    """One struct field: its name, C type (``int (*)(...)`` for a function pointer, ``char[512]``
    for an array), what it means, and for a statistics counter its key in Result.stats."""

    name: str
    ctype: str
    doc: str = ""
    stat: str | None = None

    def c(self) -> str:
        """The declaration ``<type> <name>`` (without ``;``)."""
        if "(*)" in self.ctype:
            return self.ctype.replace("(*)", f"(*{self.name})", 1)
        if self.ctype.endswith("]"):
            base, _, dims = self.ctype.partition("[")
            return f"{base} {self.name}[{dims}"
        return f"{self.ctype}{self.name}" if self.ctype.endswith("*") else f"{self.ctype} {self.name}"


@dataclass(frozen=True)
class Struct:
    """A ``typedef struct { ... } name;`` of the drivers' interface: its fields in layout order,
    a comment, and ``sections`` ((field name, a comment line printed before it), ...)."""

    name: str
    fields: tuple[Field, ...]
    doc: str = ""
    sections: tuple[tuple[str, str], ...] = ()

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")


#: Python ``struct`` codes of the scalar C types of the options (native sizes, ``=`` standard:
#: int 4 bytes, long 8 on the platforms the runtime is built for).
_PACK = {"int": "i", "long": "q", "double": "d"}


def pack_format(struct: Struct, names: tuple[str, ...]) -> str:
    """The ``struct`` format of the fields ``names`` of ``struct`` (one code each)."""
    return "".join(_PACK[struct.field(n).ctype] for n in names)


def _comment_lines(text: str, width: int = 96) -> list[str]:
    words, lines, line = text.split(), [], ""
    for w in words:
        if line and len(line) + 1 + len(w) > width:
            lines.append(line)
            line = w
        else:
            line = f"{line} {w}" if line else w
    return lines + ([line] if line else [])


def c_struct(struct: Struct) -> str:
    """The C typedef of ``struct``, one field a line with its meaning as a comment (wrapped at 110
    columns, continued under its first word)."""
    out = []
    if struct.doc:
        lines = _comment_lines(struct.doc)
        out += [f"/* {lines[0]}"] + [f" * {ln}" for ln in lines[1:]]
        out[-1] += " */"
    out.append("typedef struct {")
    sections = dict(struct.sections)
    decls = [f.c() + ";" for f in struct.fields]
    col = max(len(d) for d in decls if len(d) <= 32) + 1
    for f, decl in zip(struct.fields, decls):
        if f.name in sections:
            out.append(f"    /* {sections[f.name]} */")
        if not f.doc:
            out.append(f"    {decl}")
            continue
        lead = f"    {decl.ljust(col)}/* " if len(decl) < col else f"    {decl} /* "
        lines = _comment_lines(f.doc, 110 - len(lead) - 3)
        out.append(lead + lines[0])
        out += [" " * len(lead) + ln for ln in lines[1:]]
        out[-1] += " */"
    out.append(f"}} {struct.name};")
    return "\n".join(out)


def cffi_struct(struct: Struct) -> str:
    """The cffi declaration of ``struct`` (every field, so that cffi checks the layout against the
    compiled header)."""
    body = " ".join(f.c() + ";" for f in struct.fields)
    return f"typedef struct {{ {body} }} {struct.name};"


def _fields(spec: str, table: dict) -> tuple[Field, ...]:
    return tuple(table[name] for name in spec.split())


#: The run-control fields at the end of every driver's options (all zero: none).
CONTROL_FIELDS = (
    Field("cancel", "int *", "NULL, or a flag another thread may set: the run stops with flag -80"),
    Field("poll", "int (*)(void *data, long done, long total)",
          "NULL, or called from the calling thread about every poll_every s with the output rows done; "
          "nonzero cancels (-80)"),
    Field("poll_data", "void *"),
    Field("poll_every", "double", "seconds between poll calls (0: 0.05)"),
    Field("max_wall", "double", "wall-clock limit of the run in seconds (0: none): flag -81"),
)
_CONTROL_SECTION = (("cancel", "run control (all zero: none)"),)


def _options(name: str, *fields: Field) -> Struct:
    return Struct(name, (*fields, *CONTROL_FIELDS), sections=_CONTROL_SECTION)


_RTOL = Field("rtol", "double", "relative tolerance")
_ATOL = Field("atol", "double", "absolute tolerance, used when atol_vec is NULL")
_MAX_STEPS = Field("max_steps", "long", "step budget over the whole run")
_MAX_STEP = Field("max_step", "double", "0: unbounded")
_MIN_STEP = Field("min_step", "double", "0: none")
_MAX_ORDER = Field("max_order", "int", "0: the method's maximum")
_ROOTS = Field("roots", "int", "1: root finding on the model's nroot event functions")

#: The options of the native CVODE driver of every model (lcg_cvode_solve).
CVODE_OPTIONS = _options(
    "lcg_cvode_options",
    Field("method", "int", "CV_ADAMS (1) or CV_BDF (2)"),
    Field("jacobian", "int", "1: the model's Jacobian (dense, else sparse), 0: difference quotients"),
    _RTOL, _ATOL, Field("atol_vec", "const double *", "NULL, or ny absolute tolerances"), _MAX_STEPS,
    Field("first_step", "double", "0: CVODE's estimate"), _MAX_STEP, _MIN_STEP, _MAX_ORDER,
    Field("linear_solver", "int", "0: dense, 1: band (state interleaved as (q_1, q_1', q_2, ...)), 2: none, "
          "fixed-point nonlinear iteration (nonstiff problems)"),
    Field("mupper", "long", "band: upper bandwidth in the interleaved order"),
    Field("mlower", "long", "band: lower bandwidth in the interleaved order"))

#: The options of the index-1 constrained CVODE driver (lcg_cvc_solve).
CVC_OPTIONS = _options(
    "lcg_cvc_options",
    Field("method", "int", "CV_ADAMS (1) or CV_BDF (2); projection needs CV_BDF"),
    _RTOL, _ATOL, Field("atol_vec", "const double *", "NULL, or ny absolute tolerances"), _MAX_STEPS,
    Field("first_step", "double", "0: CVODE's estimate"), _MAX_STEP, _MIN_STEP, _MAX_ORDER,
    Field("alpha", "double", "Baumgarte stabilization (0: none; negative: m->natural_rate at y0, \"auto\")"),
    Field("beta", "double", "Baumgarte stabilization, as alpha"),
    Field("projection", "int", "1: project onto the constraints after each step (CVodeSetProjFn)"),
    Field("proj_tol", "double", "Gauss-Newton step tolerance of the projection"),
    Field("proj_maxit", "int", "Gauss-Newton steps at most"),
    Field("proj_err", "int", "1: project the error estimate too (CVODE's default)"),
    _ROOTS)

#: The options of the GGL IDA driver (lcg_ida_solve).
IDA_OPTIONS = _options(
    "lcg_ida_options",
    _RTOL, _ATOL, Field("atol_vec", "const double *", "NULL, or ng absolute tolerances"), _MAX_STEPS,
    Field("first_step", "double", "0: IDA's estimate"), _MAX_STEP, _MIN_STEP, Field("max_order", "int", "0: 5"),
    Field("suppress_alg", "int", "1: lambda, mu excluded from the error test (IDASetSuppressAlg)"),
    Field("jacobian", "int", "1: the model's dF/dyy + cj dF/dyp (ggl_jac), 0: difference quotients"),
    Field("calc_ic", "int", "1: IDACalcIC(IDA_YA_YDP_INIT) for lambda, mu and yp"),
    Field("ic_alg_atol", "double", "absolute tolerance of lambda, mu during IDACalcIC only (e.g. 1e8)"),
    _ROOTS,
    Field("stop_at_outputs", "int", "1: step exactly to every output time (IDASetStopTime), no interpolation"))

#: The options of the Taylor driver (lcg_taylor_solve).
TAYLOR_OPTIONS = _options(
    "lcg_taylor_options",
    Field("rtol", "double", "relative tolerance of one step"),
    Field("atol", "double", "absolute tolerance of one step, used when atol_vec is NULL"),
    Field("atol_vec", "const double *", "NULL, or ny absolute tolerances"), _MAX_STEPS, _MAX_STEP,
    Field("order", "int", "0: from the tolerances, else 2..LCG_TAYLOR_ORDER_MAX"),
    Field("rel_block", "int", "0: each component's relative tolerance on its own |y_i|; b > 0: the components "
          "from b on in blocks of b, each block's on its largest |y_i| (a run's sensitivities, one block per "
          "direction)"))

#: Every counter and record of the drivers' statistics structs, in the order of Result.stats
#: (``stat``: its key there; the evaluation counts without one are summed by the reader).
STAT_FIELDS = {f.name: f for f in (
    Field("nsteps", "long", "steps taken", stat="steps"),
    Field("njac", "long", "Jacobian evaluations", stat="jac_evals"),
    Field("nlinsetups", "long", "linear solver setups", stat="lin_setups"),
    Field("netfails", "long", "error test failures", stat="err_test_fails"),
    Field("nniters", "long", "nonlinear iterations", stat="nonlin_iters"),
    Field("nncfails", "long", "nonlinear convergence failures", stat="nonlin_conv_fails"),
    Field("nproj", "long", "projections", stat="projections"),
    Field("nprojfails", "long", "projection failures", stat="projection_fails"),
    Field("ngevals", "long", "root (event) function evaluations", stat="root_evals"),
    Field("nbacktracks", "long", "IDACalcIC line search backtracks", stat="backtracks"),
    Field("t_reached", "double", "time of the last state reached", stat="t_reached"),
    Field("h_last", "double", "last step size", stat="h_last"),
    Field("model_error", "int", "LCG_ERR_* / LCG_DAE_ERR_* from the model functions, or 0", stat="model_error"),
    Field("ic_flag", "int", "IDACalcIC's return flag", stat="ic_flag"),
    Field("alpha", "double", "the Baumgarte parameter alpha used", stat="alpha"),
    Field("beta", "double", "the Baumgarte parameter beta used", stat="beta"),
    Field("nretries", "long", "segments integrated again with shorter steps: a step had skipped a contact's flight",
          stat="contact_retries"),
    Field("max_penetration", "double", "deepest negative gap of a contact whose flight the steps could not "
          "resolve (taken as a plastic impact there), or 0", stat="max_penetration"),
    Field("nrhs", "long", "right-hand-side evaluations"),
    Field("nrhs_dq", "long", "right-hand-side evaluations of difference-quotient Jacobians"),
    Field("nres", "long", "residual evaluations"),
    Field("nres_dq", "long", "residual evaluations of difference-quotient Jacobians"),
    Field("flag", "int", "the run's flag (>= 0: success)"),
    Field("nt_done", "int", "rows of yout filled"),
    Field("message", "char[512]", "why the run failed"),
    Field("njet", "long", "Taylor jets computed (one per step, each worth order+1 right-hand sides)"),
    Field("nroot", "long", "steps whose event polynomials needed a root search"),
    Field("order", "int", "Taylor order used"),
    Field("h_min", "double", "smallest step"),
    Field("h_max", "double", "largest step"),
)}
#: Fields of the native drivers' statistics structs -> keys of Result.stats.
STAT_NAMES = {f.name: f.stat for f in STAT_FIELDS.values() if f.stat}

CVODE_STATS = Struct("lcg_cvode_stats", _fields(
    "nsteps nrhs nrhs_dq njac nlinsetups netfails nniters nncfails t_reached h_last flag model_error nt_done message",
    STAT_FIELDS))
CVC_STATS = Struct("lcg_cvc_stats", _fields(
    "nsteps nrhs nrhs_dq njac nlinsetups netfails nniters nncfails nproj nprojfails ngevals t_reached h_last alpha "
    "beta nretries max_penetration flag model_error nt_done message", STAT_FIELDS))
IDA_STATS = Struct("lcg_ida_stats", _fields(
    "nsteps nres nres_dq njac nlinsetups netfails nniters nncfails nbacktracks ngevals t_reached h_last flag ic_flag "
    "model_error nt_done message", STAT_FIELDS))
TAYLOR_STATS = Struct("lcg_taylor_stats", _fields(
    "nsteps njet nroot order t_reached h_last h_min h_max flag model_error nt_done message", STAT_FIELDS))

_EVENT_FIELDS = (
    Field("max_events", "int", "events kept at most"),
    Field("n_events", "int", "events found (may exceed max_events)"),
    Field("t", "double *", "max_events times"),
    Field("y", "double *", "max_events state rows"),
    Field("which", "int *", "the event function of each"),
    Field("direction", "int *", "its crossing direction (+1 increasing, -1 decreasing)"),
)
#: Events found by the SUNDIALS drivers' root finding (state rows of ny values on CVODE, ng on IDA).
EVENTS = Struct("lcg_events", (
    *_EVENT_FIELDS,
    Field("rootdir", "const int *", "nroot directions to watch (0 both, +1, -1), or NULL: both"),
    Field("terminal", "const int *", "nroot flags: stop at this event, or NULL: every event stops"),
    Field("terminated", "int", "1 if the run stopped at a terminal event")),
    doc="Events found by the drivers' root finding: event k at t[k], state y[k*nrow..] (nrow: ny on CVODE, ng "
        "on IDA), root function which[k], crossing direction[k]. Only the first max_events are stored.")
#: Events found by the Taylor driver on its step polynomials.
TAYLOR_EVENTS = Struct("lcg_taylor_events", (
    *_EVENT_FIELDS, Field("terminated", "int", "1 if a terminal event ended the run")),
    doc="Events found by root finding on the step polynomials: event k at t[k] with state y[k*ny ...], event "
        "function which[k], direction[k]. Only the first max_events are stored; n_events counts them all.")


#: One input signal of a model as a table (lcg_inputs.h): a piecewise cubic over its breakpoints.
INPUT_TABLE = Struct("lcg_input_table", (
    Field("slot", "int", "the run-time parameter p[slot] the input is"),
    Field("n", "int", "breakpoints (at least 1)"),
    Field("t", "const double *", "n increasing breakpoint times"),
    Field("c", "const double *", "4 (n + 1) coefficients: piece k is c[4k] + c[4k+1] s + c[4k+2] s^2 + c[4k+3] s^3, "
          "s = t - t_(k-1) (t_0 for k = 0)")),
    doc="An input u(t) = p[slot] given by a table: piece 0 before t_0, piece k (0 < k < n) on [t_(k-1), t_k), "
        "piece n from t_(n-1) on.")
#: The input tables of a run.
INPUTS = Struct("lcg_inputs", (
    Field("count", "int", "tables"),
    Field("tables", "const lcg_input_table *", "count tables, each its own slot"),
    Field("nbreak", "int", "restart times: the driver stops at each and starts afresh (CVodeReInit)"),
    Field("breaks", "const double *", "nbreak increasing restart times (where an input jumps or kinks)")),
    doc="The input tables of a run: the driver sets p[slot] of each from its table at every evaluation time.")


def ensemble(name: str, model: str, yp0: bool = False, events: bool = False, roots: bool = False,
             inputs: bool = False) -> Struct:
    """The ensemble struct of a driver (lcg_pool.h): ``model`` the type of the model's table,
    ``yp0`` an initial yp0 per member (IDA), ``events`` root finding, ``roots`` the event
    functions beside the model's table (:data:`ODE_ROOTS`; the ODE of a scene), ``inputs`` input
    tables per member (lcg_inputs.h)."""
    fields = [
        Field("model", f"const {model} *", "the model every member integrates"),
        Field("nmem", "long"), Field("nthreads", "int"),
        Field("p", "const double *", "member i: p + i*p_stride (p_stride 0: shared; NULL: no parameters)"),
        Field("p_stride", "long"),
        Field("y0", "const double *", "member i: y0 + i*y0_stride"), Field("y0_stride", "long")]
    if yp0:
        fields += [Field("yp0", "const double *", "member i: yp0 + i*yp0_stride"), Field("yp0_stride", "long")]
    fields += [
        Field("nt", "int"), Field("tout", "const double *"),
        Field("final", "double *", "nmem x (NROW + NOUT): state and outputs at the last time reached"),
        Field("traj", "double *", "nmem x nt x ncol: columns col[] of (state | outputs); NaN past the end"),
        Field("ncol", "int"), Field("col", "const int *"),
        Field("flag", "int *", "return flag of each member (0 success)"),
        Field("nt_done", "int *", "output rows reached"),
        Field("t_reached", "double *"), Field("wall", "double *", "seconds"),
        Field("counts", "long *", "nmem x 8: steps, rhs evals, jac evals, error test fails, nonlinear convergence "
              "fails, model error, events, terminated"),
        Field("messages", "char *", "max_messages x 256: solver messages of failed members (truncated)"),
        Field("max_messages", "long"),
        Field("message_member", "long *", "the member of each message"),
        Field("n_messages", "long", "failed members with a message (may exceed max_messages)")]
    if events:
        fields += [
            Field("max_events", "int", "events kept per member run (root finding; 0: 64)"),
            Field("rootdir", "const int *", "NROOT directions of the event functions (0: both), or NULL"),
            Field("terminal", "const int *", "NROOT flags: the event ends the run, or NULL (all terminal)"),
            Field("ev_t", "double *", "NULL, or nmem x max_events (0: 64): the times of each member's first events "
                  "(as many as counts' events, at most max_events)"),
            Field("ev_y", "double *", "NULL, or nmem x max_events x NROW: the state row at each"),
            Field("ev_which", "int *", "NULL, or nmem x max_events: the event function of each"),
            Field("ev_direction", "int *", "NULL, or nmem x max_events: its crossing direction")]
    if roots:
        fields.append(Field("roots", "const lcg_ode_roots *", "NULL, or the event functions every member locates"))
    if inputs:
        fields += [Field("inputs", "const lcg_inputs *", "NULL, or the input tables of member i: inputs[i] (p_stride > "
                         "0), inputs[0] (p_stride 0)")]
    fields += [
        Field("poll", "int (*)(void *data, long done, long total)",
              "NULL, or called from the calling thread about every poll_every s with the members done; "
              "nonzero cancels"),
        Field("poll_data", "void *"),
        Field("poll_every", "double", "seconds (0: 0.05)"),
        Field("cancel", "int", "set (by anyone) to stop: running members end with -80"),
        Field("done", "long", "members finished (the progress counter)"),
        Field("next", "long", "members started")]
    return Struct(name, tuple(fields), doc=(
        "An ensemble of nmem runs that differ in p and the initial state, spread over nthreads threads (members "
        "taken in turn from a shared counter; each member is a run of the single-run solver with its own solver "
        "context, so its numbers are those of the same run alone). Arrays are by member; NULL where not wanted. "
        "The caller presets flag[i] (e.g. -82: never started)."))


#: The event functions of an ODE run (the CVODE driver of a scene, lcg_cvode_solve_events): generated
#: apart from the model (a library per set of events), so that a model's code is the same with or
#: without events.
ODE_ROOTS = Struct("lcg_ode_roots", (
    Field("nroot", "int", "event functions"),
    Field("roots", "int (*)(double t, const double *y, const double *p, double *gout)",
          "gout[nroot] = the event functions at (t, y) with the parameters p; 0 or a model error code")),
    doc="The event functions of an ODE run: their number and the function computing them.")


@dataclass(frozen=True)
class Driver:
    """A native driver's interface types, in the order of its generated header
    ``lcg_<name>_types.h`` (which includes ``include``, the header of the model table it takes)."""

    name: str
    include: str
    structs: tuple[Struct, ...]

    @property
    def header_name(self) -> str:
        return f"lcg_{self.name}_types.h"


#: The model-independent drivers: CVODE (ODEs), index-1 CVODE and GGL IDA (constrained; their
#: events record: "dae"), Taylor.
DRIVERS = {d.name: d for d in (
    Driver("inputs", "lcg_model.h", (INPUT_TABLE, INPUTS)),
    Driver("cvode", "lcg_inputs_types.h", (CVODE_OPTIONS, CVODE_STATS, ODE_ROOTS,
                                           ensemble("lcg_cvode_ensemble", "lcg_model", events=True, roots=True,
                                                    inputs=True))),
    Driver("dae", "lcg_dae_model.h", (EVENTS,)),
    Driver("cvc", "lcg_dae_types.h", (CVC_OPTIONS, CVC_STATS,
                                      ensemble("lcg_cvc_ensemble", "lcg_dae_model", events=True))),
    Driver("ida", "lcg_dae_types.h", (IDA_OPTIONS, IDA_STATS,
                                      ensemble("lcg_ida_ensemble", "lcg_dae_model", yp0=True, events=True))),
    Driver("taylor", "lcg_taylor_model.h", (TAYLOR_OPTIONS, TAYLOR_STATS, TAYLOR_EVENTS,
                                            ensemble("lcg_taylor_ensemble", "lcg_taylor_model"))),
)}


def standalone(struct: Struct, prefix: str) -> Struct:
    """``struct`` as a model's own driver declares it (``lcg_taylor_options`` ->
    ``<prefix>_taylor_options``; no run-control fields: a standalone driver has none)."""
    fields = tuple(f for f in struct.fields if f not in CONTROL_FIELDS and f.name != "rel_block")
    return Struct(prefix + struct.name[len("lcg"):], fields, struct.doc)


def _fn(name: str, sig: str) -> Field:
    return Field(name, f"int (*)({sig})")


#: The function table of a compiled model (lcg_model.h; its functions those of MODEL_FUNCTIONS).
MODEL_TABLE = Struct("lcg_model", (
    *(Field(n, "int") for n in ("abi", "nq", "nz", "ny", "np", "nout")),
    *(_fn(sig.name, ", ".join(a.c() for a in sig.args)) for sig in MODEL_FUNCTIONS.values()),
    Field("jac_nnz", "int"), Field("jac_colptr", "const int *"), Field("jac_rowind", "const int *")))
#: The function table of a compiled constrained model (lcg_dae_model.h).
DAE_TABLE = Struct("lcg_dae_model", (
    *(Field(n, "int") for n in ("abi", "nq", "ny", "nj", "njh", "ng", "np", "nout", "nroot")),
    *(_fn(sig.name, ", ".join(a.c() for a in sig.args)) for sig in DAE_FUNCTIONS.values()),
    Field("model", "const lcg_model *")))
#: The table of a model's Taylor jet (lcg_taylor_model.h).
TAYLOR_TABLE = Struct("lcg_taylor_model", (
    *(Field(n, "int") for n in ("abi", "nq", "nz", "ny", "np", "nout", "ne", "nrows", "order_max")),
    Field("work_size", "size_t"),
    _fn("start", "void *work, const double *p"),
    _fn("jet", "void *work, double *X, double t, const double *y, int kmax"),
    _fn("outputs", "double t, const double *y, const double *p, double *out"),
    Field("event_row", "const int *"), Field("event_direction", "const int *"), Field("event_terminal", "const int *")))


def c_header(driver: Driver, version: str) -> str:
    """``lcg_<driver>_types.h``: the driver's structs as C, rendered from their declaration."""
    guard = f"LCG_{driver.name.upper()}_TYPES_H"
    parts = [f"/* {driver.header_name} -- generated by lagcodegen {version} from lagcodegen/codegen/signatures.py:\n"
             f" * the structs of the {driver.name} driver's interface (lcg_{driver.name}.h). */",
             f"#ifndef {guard}\n#define {guard}\n\n#include \"{driver.include}\""]
    parts += [c_struct(s) for s in driver.structs]
    parts.append(f"#endif /* {guard} */\n")
    return "\n\n".join(parts)

#: The contact table of a constrained model with contacts (lagcodegen/runtime/lcg_imp_model.h,
#: <prefix>_impact.c): the contacts' gaps, the index-1 right-hand side with the persistent
#: contacts held, the impact; read by the impact driver (lcg_imp.c).
IMP_TABLE = Struct("lcg_imp_model", (
    *(Field(n, "int") for n in ("abi", "nq", "nj", "nk", "nrow")),
    _fn("gaps", "double t, const double *y, const double *p, double *g, double *w"),
    _fn("crhs", "double t, const double *y, const double *p, double alpha, double beta, const int *active, "
                "double *ydot, double *lam"),
    _fn("impact", "double t, const double *y, const double *p, const int *active, const double *e, double *ynew, "
                  "double *P"),
    Field("dae", "const lcg_dae_model *")))

#: The friction table of a constrained model with Coulomb friction on a contact
#: (lagcodegen/runtime/lcg_imp_model.h, <prefix>_impact.c): the model's numbers at a state, from
#: which the impact driver (lcg_imp.c) solves the stick/slip modes.
IMP_FRICTION_TABLE = Struct("lcg_imp_friction", (
    *(Field(n, "int") for n in ("abi", "njh", "nt")),
    Field("tangent_of", "const int *"),
    _fn("eval", "double t, const double *y, const double *p, double *M, double *F, double *R, double *s, double *h, "
                "double *gam, double *qd"),
    Field("imp", "const lcg_imp_model *")))
