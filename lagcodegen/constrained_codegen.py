"""Generated code for constrained systems (eq. 4.5): the augmented index-1 system, the GGL residual.

:func:`generate_constrained_c` renders templates/c/dae.c.j2 (accelerations and multipliers from
[M A^T; A 0][q''; -lambda] = [F; gamma], constraint residuals, projection, outputs, events) and,
for the GGL formulation, the DAE residual F(t, y, y') and its Jacobian dF/dy + cj dF/dy' for
IDA; with ``lang="fortran"`` the same functions come from templates/fortran/dae.f90.j2 (bound
to the same C names, evaluating the same operations: :func:`constrained_blocks` builds the
expression blocks once for both languages). The native drivers are
templates/c/cvode_constrained_driver.c.j2 and ida_driver.c.j2 (C in both cases);
:mod:`lagcodegen.dae` compiles and runs them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import symengine as se

from . import __version__
from .codegen import LANGUAGES, _symbol_map, emit_block, environment, generate_c
from .constraints import ConstrainedSystem
from .derivation import derive, to_se
from .errors import ModelError
from .events import event_list
from .scene import Scene

#: Output groups of constrained systems, besides the model's (energy, positions, momenta...).
CONSTRAINT_OUTPUT_GROUPS = ("lambda", "constraint_forces", "residuals", "inequalities")
DEFAULT_OUTPUTS = ("energy", "lambda", "residuals")

# ---------------------------------------------------------------------- symbolic pieces
class _Symbolic:
    """symengine pieces of a constrained system: M, F, A, A0, s = A q' + A0, gamma, f."""

    def __init__(self, system: ConstrainedSystem, eom):
        model = system.model
        self.system = system
        self.eom = eom
        self.n = model.n
        self.q = [se.Symbol(s.name) for s in model.coords]
        self.v = [se.Symbol(s.name) for s in model.speeds]
        self.t = se.Symbol(model.t.name)
        rows = system.rows()
        self.A = [[to_se(a, f"constraint {r.index}") for a in r.A] for r in rows]
        self.A0 = [to_se(r.A0, f"constraint {r.index}") for r in rows]
        self.f = [to_se(f, f"holonomic constraint {j}") for j, f in enumerate(system.holonomic)]
        self.s = [sum((a * v for a, v in zip(row, self.v)), se.Integer(0)) + a0 for row, a0 in zip(self.A, self.A0)]
        self.gamma = []
        for s in self.s:  # gamma = -d/dt (A q' + A0) with q'' excluded
            d = se.diff(s, self.t)
            for q, v in zip(self.q, self.v):
                d = d + se.diff(s, q) * v
            self.gamma.append(-d)
        self.lam = [se.Symbol(m.name) for m in system.multipliers]
        self.J = len(rows)
        self.JH = len(self.f)
        self.M = eom.M_se
        self.F = eom.F_se


def _constrained_outputs(system: ConstrainedSystem, sym: _Symbolic, scene: Scene,
                         names: Sequence[str]) -> list[tuple[str, object]]:
    """(name, symengine expression) of the requested outputs, groups expanded."""
    model = system.model
    avail = dict(scene.available_outputs())
    coord_names = [q.name for q in model.coords]
    lam_names, force_names, resid_names, ineq_names = [], [], [], []
    for j in range(sym.J):
        avail[f"lambda_{j}"] = sym.lam[j]
        lam_names.append(f"lambda_{j}")
        for i, c in enumerate(coord_names):
            avail[f"R_{j}_{c}"] = sym.lam[j] * sym.A[j][i]
            force_names.append(f"R_{j}_{c}")
    for j in range(sym.JH):
        avail[f"g_{j}"] = sym.f[j]
        resid_names.append(f"g_{j}")
    for j in range(sym.J):
        avail[f"gdot_{j}"] = sym.s[j]
        resid_names.append(f"gdot_{j}")
    for k, g in enumerate(system.inequalities):
        avail[f"ineq_{k}"] = to_se(g, f"inequality constraint {k}")
        ineq_names.append(f"ineq_{k}")
    groups = {"lambda": lam_names, "constraint_forces": force_names, "residuals": resid_names,
              "inequalities": ineq_names,
              "momenta": [f"p_{c}" for c in coord_names],
              "positions": [f"{pt.name}_{a}" for pt in model.points.values() for a in "xyz"[:pt.dim]]}
    out: list[str] = []
    for item in names:
        if item in groups:
            out += groups[item]
        elif item in avail:
            out.append(item)
        else:
            raise ModelError(f"unknown output {item!r} (groups: {', '.join(CONSTRAINT_OUTPUT_GROUPS)}, "
                             f"energy, momenta, positions, ...; single outputs: "
                             f"{', '.join(k for k in avail if k not in ('momenta', 'positions'))})")
    seen: list[str] = []
    for nme in out:
        if nme not in seen:
            seen.append(nme)
    return [(nme, avail[nme]) for nme in seen]


def _uses(exprs, symbols) -> bool:
    symbols = set(symbols)
    return any(se.sympify(e).free_symbols & symbols for e in exprs)


# ---------------------------------------------------------------------- code generation
@dataclass
class ConstrainedCodeInfo:
    """Layout of the generated constrained code."""

    prefix: str
    n: int
    J: int
    JH: int
    ng: int
    output_names: list
    events: list
    ggl: bool
    ggl_jac: bool
    folded: dict = field(default_factory=dict)  # parameters folded into the code, with their values
    lang: str = "c"  # language of the model functions ("c" or "fortran"); the drivers are C


@dataclass
class ExpressionBlock:
    """One common-subexpression-eliminated block of generated code, language neutral: the
    targets are tuples (array name, indices...) in the C backend's 0-based indexing, the
    expressions in the C backend's symbols (``y[i]``, ``p[k]``, ``lam[j]``, ``yp[i]``, ``t``,
    ``cj``). :func:`c_block` prints it as C, :mod:`lagcodegen.fortran` as Fortran, both after
    the same elimination, so that the two languages evaluate the same operations."""

    targets: list
    exprs: list

    def __bool__(self) -> bool:
        return bool(self.exprs)


def _c_target(target: tuple, ng: int) -> str:
    name, *ix = target
    if name == "M":
        i, j = ix
        return f"M[{i}][{j}]" if i == j else f"M[{i}][{j}] = M[{j}][{i}]"
    if name == "jac":  # (row, column), column-major
        row, col = ix
        return f"jac[{col * ng + row}]"
    return name + "".join(f"[{k}]" for k in ix)


def c_block(block: ExpressionBlock, ng: int = 0) -> str:
    """The C statements of ``block`` (see :func:`lagcodegen.codegen.emit_block`)."""
    return emit_block([_c_target(tg, ng) for tg in block.targets], block.exprs)


@dataclass
class ConstrainedBlocks:
    """Everything the constrained templates need besides the sizes: the expression blocks
    (mf: M, F; con: A, s, g; gam; out; roots; ggl_res; ggl_jac) and the output and event lists."""

    scene: Scene
    n: int
    J: int
    JH: int
    ng: int
    blocks: dict
    outputs: list  # (name, symengine expression)
    events: list
    outputs_use_lam: bool
    roots_use_lam: bool


def constrained_blocks(system: ConstrainedSystem, scene: Scene, *, ggl: bool = False, ggl_jacobian: bool = True,
                       outputs: Sequence[str] = DEFAULT_OUTPUTS, events: Iterable = ()) -> ConstrainedBlocks:
    """The expression blocks of the constrained code of ``system`` (symbols renamed as in ``scene``)."""
    sym = _Symbolic(system, scene.eom)
    n, J, JH = sym.n, sym.J, sym.JH
    ng = 2 * n + J + JH
    base = _symbol_map(scene)

    def c(e, sub=base):
        return se.sympify(e).xreplace(sub)

    blocks = {}
    # M, F
    targets, exprs = [], []
    for i in range(n):
        for j in range(i, n):
            targets.append(("M", i, j))
            exprs.append(c(sym.M[i][j]))
    for i in range(n):
        targets.append(("F", i))
        exprs.append(c(sym.F[i]))
    blocks["mf"] = ExpressionBlock(targets, exprs)
    # A, s, g
    targets, exprs = [], []
    for r in range(J):
        for i in range(n):
            targets.append(("A", r, i))
            exprs.append(c(sym.A[r][i]))
        targets.append(("s", r))
        exprs.append(c(sym.s[r]))
    for k in range(JH):
        targets.append(("g", k))
        exprs.append(c(sym.f[k]))
    blocks["con"] = ExpressionBlock(targets, exprs)
    blocks["gam"] = ExpressionBlock([("gam", r) for r in range(J)], [c(e) for e in sym.gamma])

    # outputs and roots: the multipliers are the array lam[]
    out_sub = dict(base)
    out_sub.update({lam: se.Symbol(f"lam[{j}]") for j, lam in enumerate(sym.lam)})
    outs = _constrained_outputs(system, sym, scene, list(outputs))
    blocks["out"] = ExpressionBlock([("out", k) for k in range(len(outs))], [c(e, out_sub) for _, e in outs])
    evs = event_list(system, events)
    root_exprs = [to_se(ev.expr, f"event {ev.name!r}") for ev in evs]
    blocks["roots"] = ExpressionBlock([("gout", k) for k in range(len(evs))], [c(e, out_sub) for e in root_exprs])

    # GGL residual and Jacobian
    blocks["ggl_res"] = blocks["ggl_jac"] = ExpressionBlock([], [])
    if ggl:
        qp = [se.Symbol(f"__qp{i}") for i in range(n)]
        vp = [se.Symbol(f"__vp{i}") for i in range(n)]
        mu = [se.Symbol(f"__mu{k}") for k in range(JH)]
        cj = se.Symbol("cj")
        res = []
        for i in range(n):
            res.append(qp[i] - sym.v[i] - sum((sym.A[k][i] * mu[k] for k in range(JH)), se.Integer(0)))
        for i in range(n):
            res.append(sum((sym.M[i][j] * vp[j] for j in range(n)), se.Integer(0)) - sym.F[i]
                       - sum((sym.A[r][i] * sym.lam[r] for r in range(J)), se.Integer(0)))
        res += list(sym.f)
        res += list(sym.s)
        gsub = dict(base)
        gsub.update({lam: se.Symbol(f"y[{2 * n + j}]") for j, lam in enumerate(sym.lam)})
        gsub.update({m: se.Symbol(f"y[{2 * n + J + k}]") for k, m in enumerate(mu)})
        gsub.update({x: se.Symbol(f"yp[{i}]") for i, x in enumerate(qp)})
        gsub.update({x: se.Symbol(f"yp[{n + i}]") for i, x in enumerate(vp)})
        blocks["ggl_res"] = ExpressionBlock([("rr", i) for i in range(ng)], [c(e, gsub) for e in res])
        if ggl_jacobian:
            yvars = sym.q + sym.v + sym.lam + mu
            ypvars = qp + vp
            targets, exprs = [], []
            for col, var in enumerate(yvars):
                for row, r in enumerate(res):
                    d = se.diff(r, var)
                    if col < 2 * n:
                        d = d + cj * se.diff(r, ypvars[col])
                    if d != 0:
                        targets.append(("jac", row, col))
                        exprs.append(c(d, gsub))
            blocks["ggl_jac"] = ExpressionBlock(targets, exprs)
    return ConstrainedBlocks(scene, n, J, JH, ng, blocks, outs, evs, _uses([e for _, e in outs], sym.lam),
                             _uses(root_exprs, sym.lam))


#: Languages of the generated constrained code (the native drivers are C in both cases).


def generate_constrained_c(system: ConstrainedSystem, *, ggl: bool = False, ggl_jacobian: bool = True,
                           outputs: Sequence[str] = DEFAULT_OUTPUTS, events: Iterable = (),
                           runtime_parameters=None, values=None, prefix: str | None = None, lang: str = "c",
                           drivers: bool = True):
    """Generated code of a constrained system: the model's own files plus ``<prefix>_dae.h`` and
    its implementation (augmented-system solve, projection, outputs, roots, GGL residual and
    Jacobian) and, with ``drivers``, the native drivers ``<prefix>_cvc.[ch]`` (CVODE) and, with
    ``ggl``, ``<prefix>_ida.[ch]`` (IDA).

    ``lang``: ``"c"`` (``<prefix>.c``, ``<prefix>_dae.c``, C99) or ``"fortran"`` (``<prefix>.f90``
    and ``<prefix>_dae.f90``, Fortran 2008 modules whose functions are bound to the same C
    names and signatures, see :func:`lagcodegen.fortran.generate_constrained_fortran_source`);
    the headers and the drivers are the same C files in both cases.

    Returns (GeneratedCode ready for :func:`lagcodegen.build.build`, ConstrainedCodeInfo).
    """
    if lang not in LANGUAGES:
        raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
    model = system.model
    eom = derive(model)
    if eom.quadratures:
        raise ModelError("constrained systems with quadrature states are not supported")
    scene = Scene(eom, jacobian=False, outputs=(), runtime_parameters=runtime_parameters,
                  values=dict(values or {}), prefix=prefix)
    if lang == "fortran":
        from .fortran import check_prefix, generate_fortran
        check_prefix(scene.prefix, suffix="_dae_err_projection")
        code = generate_fortran(scene)
    else:
        code = generate_c(scene)
    cb = constrained_blocks(system, scene, ggl=ggl, ggl_jacobian=ggl_jacobian, outputs=outputs, events=events)
    n, J, JH, ng = cb.n, cb.J, cb.JH, cb.ng
    outs, evs, blocks = cb.outputs, cb.events, cb.blocks

    pre = code.prefix
    ctx = dict(prefix=pre, PREFIX=pre.upper(), version=__version__, model_name=model.name, n=n, nj=J, njh=JH,
               ng=ng, np=len(scene.runtime_parameters), nout=len(outs), nroot=len(evs),
               state_names=code.state_names, param_names=list(scene.runtime_parameters),
               outputs=[name for name, _ in outs], roots=[f"{ev.name}: {ev.expr}" for ev in evs],
               ggl=ggl, ggl_jac=bool(ggl and ggl_jacobian), outputs_use_lam=cb.outputs_use_lam,
               roots_use_lam=cb.roots_use_lam)
    env = environment()
    files = {f"{pre}_dae.h": env.get_template("c/dae.h.j2").render(**ctx)}
    if lang == "fortran":
        from .fortran import generate_constrained_fortran_source
        files[f"{pre}_dae.f90"] = generate_constrained_fortran_source(cb, ctx)
    else:
        files[f"{pre}_dae.c"] = env.get_template("c/dae.c.j2").render(
            **ctx, mf=c_block(blocks["mf"]), con=c_block(blocks["con"]), gam=c_block(blocks["gam"]),
            out=c_block(blocks["out"]), root_block=c_block(blocks["roots"]), ggl_res=c_block(blocks["ggl_res"]),
            ggl_jac_block=c_block(blocks["ggl_jac"], ng))
    headers = [f"{pre}_dae.h"]
    if drivers:
        files[f"{pre}_cvc.h"] = env.get_template("c/cvode_constrained_driver.h.j2").render(**ctx)
        files[f"{pre}_cvc.c"] = env.get_template("c/cvode_constrained_driver.c.j2").render(**ctx)
        headers.append(f"{pre}_cvc.h")
        if ggl:
            files[f"{pre}_ida.h"] = env.get_template("c/ida_driver.h.j2").render(**ctx)
            files[f"{pre}_ida.c"] = env.get_template("c/ida_driver.c.j2").render(**ctx)
            headers.append(f"{pre}_ida.h")
            code.sundials_libs = tuple(dict.fromkeys((*code.sundials_libs, "ida")))
    code.files.update(files)
    code.cffi_headers = list(dict.fromkeys([*code.cffi_headers, *headers]))
    code.cdef_extra = (code.cdef_extra + "\n" + _cdef(pre, bool(evs), ggl, bool(ggl and ggl_jacobian),
                                                       drivers)).strip()
    info = ConstrainedCodeInfo(pre, n, J, JH, ng, [name for name, _ in outs], evs, ggl, bool(ggl and ggl_jacobian),
                               dict(scene.folded), lang)
    return code, info


def generate_constrained_fortran(system: ConstrainedSystem, **options):
    """:func:`generate_constrained_c` with ``lang="fortran"``."""
    return generate_constrained_c(system, lang="fortran", **options)


def _cdef(p: str, roots: bool, ggl: bool, ggl_jac: bool, drivers: bool = True) -> str:
    """cffi declarations (API mode: the struct layouts come from the headers via '...;')."""
    lines = [f"""
typedef struct {{
    int max_events; int n_events; double *t; double *y; int *which; int *direction;
    const int *rootdir; const int *terminal; int terminated; ...;
}} {p}_events;
int {p}_kkt(double t, const double *y, const double *p, double alpha, double beta, double *acc, double *lam);
int {p}_crhs(double t, const double *y, const double *p, double alpha, double beta, double *ydot);
int {p}_residuals(double t, const double *y, const double *p, double *g, double *s);
int {p}_project(double t, const double *y, const double *p, double tol, int maxit, double *ynew, double *err);
int {p}_coutputs(double t, const double *y, const double *lam, const double *p, double *out);"""]
    if drivers:
        lines.append(f"""typedef struct {{
    int method; double rtol; double atol; const double *atol_vec; long max_steps; double first_step;
    double max_step; double min_step; int max_order; double alpha; double beta; int projection;
    double proj_tol; int proj_maxit; int proj_err; int roots; ...;
}} {p}_cvc_options;
typedef struct {{
    long nsteps, nrhs, nrhs_dq, njac, nlinsetups, netfails, nniters, nncfails, nproj, nprojfails, ngevals;
    double t_reached; double h_last; int flag; int model_error; int nt_done; char message[512]; ...;
}} {p}_cvc_stats;
int {p}_cvc_solve(const double *p, const double *y0, int nt, const double *tout, double *yout, double *out,
                  const {p}_cvc_options *opt, {p}_cvc_stats *st, {p}_events *ev);""")
    if roots:
        lines.append(f"int {p}_roots(double t, const double *y, const double *lam, const double *p, double *gout);")
    if ggl:
        lines.append(f"""
int {p}_ggl_res(double t, const double *yy, const double *yp, const double *p, double *rr);""")
        if drivers:
            lines[-1] += f"""
typedef struct {{
    double rtol; double atol; const double *atol_vec; long max_steps; double first_step; double max_step;
    double min_step; int max_order; int suppress_alg; int jacobian; int calc_ic; double ic_alg_atol; int roots;
    int stop_at_outputs; ...;
}} {p}_ida_options;
typedef struct {{
    long nsteps, nres, nres_dq, njac, nlinsetups, netfails, nniters, nncfails, nbacktracks, ngevals;
    double t_reached; double h_last; int flag; int ic_flag; int model_error; int nt_done; char message[512]; ...;
}} {p}_ida_stats;
int {p}_ida_solve(const double *p, const double *yy0, const double *yp0, int nt, const double *tout,
                  double *yout, double *out, const {p}_ida_options *opt, {p}_ida_stats *st, {p}_events *ev);"""
        if ggl_jac:
            lines.append(f"int {p}_ggl_jac(double t, double cj, const double *yy, const double *yp, "
                         f"const double *p, double *jac);")
    return "\n".join(lines)


# ---------------------------------------------------------------------- public API
