"""Forward sensitivities of a constrained system in the index-1 form on CVODE: the system's
sensitivity functions (``<prefix>_csens.c``, :mod:`lagcodegen.codegen.sensitivity_constrained`)
compiled on first use per compiled system, and one call of the runtime's sensitivity driver
(``lagcodegen/runtime/lcg_cvsens.c``, the ODE's: the augmented ODE with the states' Newton matrix
reused for every sensitivity block) on the table of the index-1 right-hand side that file
defines (its exact Jacobian from the same tangents).

Directions as for the ODE (:mod:`.sensitivity`): a run-time parameter, ``"<q>(0)"``,
``"<q>_dot(0)"``. Drift: the run integrates the Baumgarte-stabilized index-1 equations (eq. 4.5)
with the run's alpha, beta ("auto": the natural rate at the initial state, as the plain run),
and the sensitivities are the exact derivatives of that ODE, so their own constraint residuals
(G S_q + df/dp and its velocity form) are damped by the same rates. With ``projection=True``
(BDF) the state is projected onto the constraints after each step as in the plain run
(CVodeSetProjFn: Gauss-Newton on the positions, then the velocities) and every sensitivity
block through that projection linearized at the projected state (the initial projection's
formula below), so that G S_q + df/dp = 0 and its velocity form hold after every step; the error
estimate is projected block by block onto the tangent spaces. The initial sensitivities
are those of the projection onto the constraints simulate() applies to the initial state
(``initial="check"`` or ``"project"``; ``"none"``: unit vectors): a direction that leaves the
constraints is projected back onto them, and a parameter of the constraints moves the initial
state with them. Multipliers: the outputs ``lambda_<j>`` (and every output using them) get their
sensitivities from the tangent of the augmented system.
"""

from __future__ import annotations

import ctypes
import time

import numpy as np

from ...errors import LagcodegenError, ModelError
from ...libraries import constrained_sensitivity_library
from ...result import Result
from ..base import tolerances
from ..control import CANCELLED, install, raise_pending
from ..request import StepControl
from .sensitivity import check_family, driver_result, parse_directions, sens_options, sens_runtime


class ConstrainedSensitivityFunctions:
    """The compiled ``<prefix>_csens_*`` functions of a constrained system ``sim``, as function
    pointers of the sensitivity driver's module (``rt``); ``library`` keeps the library open."""

    def __init__(self, sim):
        built = constrained_sensitivity_library(sim.system, sim.compiled.code, sim.output_names)  # the build stage's
        self.library, self.path = built.handle, built.path
        self.rt = sens_runtime()
        self.poll = install(self.rt)  # Ctrl-C during a run
        ffi = self.rt.ffi
        lib = self.library
        self.rhs = ffi.cast("lcg_sens_rhs_fn", built.address("rhs"))
        self.out = ffi.cast("lcg_sens_out_fn", built.address("outputs"))
        self.project = ffi.cast("lcg_sens_proj_fn", built.address("project"))
        getter = getattr(lib, built.functions["model_table"])
        getter.restype, getter.argtypes = ctypes.c_void_p, []
        self.table = ffi.cast("const lcg_model *", getter())
        initial = getattr(lib, built.functions["initial"])
        dp, ip = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
        initial.restype = ctypes.c_int
        initial.argtypes = [ctypes.c_double, dp, dp, ctypes.c_int, ip, dp]
        self._initial = initial

    def initial(self, t0: float, y0: np.ndarray, p_ext: np.ndarray, which: np.ndarray, s0: np.ndarray) -> np.ndarray:
        """``s0`` (ns, 2n) through the linearized initial projection at the consistent (t0, y0)."""
        s = np.ascontiguousarray(s0, dtype=float).copy()
        dp, ip = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
        y0 = np.ascontiguousarray(y0, dtype=float)
        which = np.ascontiguousarray(which, dtype=np.intc)
        rc = self._initial(float(t0), y0.ctypes.data_as(dp), p_ext.ctypes.data_as(dp), int(which.size),
                           which.ctypes.data_as(ip), s.ctypes.data_as(dp))
        if rc != 0:
            raise ModelError("sensitivities: the initial sensitivities cannot be projected onto the constraints "
                             "(the constraint Jacobian is rank deficient or a value is not finite at the initial "
                             "state)")
        return s


def functions(sim) -> ConstrainedSensitivityFunctions:
    """The sensitivity functions of ``sim``, built on first use (kept with its compiled model's
    ``artifacts``)."""
    return sim.compiled.artifacts.get(ConstrainedSensitivityFunctions, "constrained",
                                      lambda: ConstrainedSensitivityFunctions(sim))


def directions(sim, names) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, which, s0) of the directions ``names`` of ``sim`` (as
    :func:`.sensitivity.directions`: which[j] the run-time parameter index or -1, s0 (ns, 2n) the
    unit vectors of initial values before the projection). Unknown or repeated names raise."""
    n = sim.n
    return parse_directions(names, params=list(sim.param_names), states=list(sim.state_names[:n]), n=n, ny=2 * n,
                            folded=sim.info.folded or {}, listed_in="runtime_parameters of compile_constrained")


def run_index1(family, sim, t: np.ndarray, y0: np.ndarray, p: np.ndarray, rtol: float, atol, *, roots: bool,
               initial: str) -> Result:
    """A sensitivity run of the index-1 form of ``sim`` from the consistent state ``y0`` with the
    options of ``family`` (a :class:`~lagcodegen.solvers.cvode.CVODE`; module docstring)."""
    check_family(family)
    if roots:
        raise LagcodegenError("sensitivities with events: not supported (run the sensitivities with events=False, "
                              "or locate the events in a run of their own)")
    method, projection, alpha, beta = family.index1_settings(sim, float(t[0]), y0, p)
    if alpha < 0 or beta < 0:  # "auto": the natural rate at the initial state, as the native driver takes it
        try:
            rate = sim.natural_rate(float(t[0]), y0, p)
        except LagcodegenError:  # the run reports the model's error at its first step
            rate = 0.0
        alpha, beta = (rate if alpha < 0 else alpha), (rate if beta < 0 else beta)
    names, which, s0 = directions(sim, family.sensitivities)
    fns = functions(sim)
    ffi, lib = fns.rt.ffi, fns.rt.lib
    n = sim.n
    ny, ns, nt = 2 * n, len(names), t.size
    nout = len(sim.output_names)
    p_ext = np.concatenate([np.asarray(p, dtype=float), [alpha, beta, family.proj_tol, family.proj_maxit]])
    if initial in ("check", "project"):
        s0 = fns.initial(float(t[0]), y0, p_ext, which, s0)
    rtol, atol = tolerances(rtol, atol, ny)
    yout = np.empty((nt, ny))
    sout = np.empty((nt, ns, ny))
    out = np.empty((nt, max(nout, 1)))
    dout = np.empty((nt, ns, max(nout, 1)))
    control = StepControl.of(family, rtol, atol, method=method, jacobian=True)
    opt, atol_all = sens_options(fns.rt.ffi, fns.poll, control, ny, ns)
    if projection:
        opt.project = fns.project
    st = ffi.new("lcg_cvsens_stats *")
    fb = ffi.from_buffer
    y0 = np.ascontiguousarray(y0, dtype=float)
    start = time.perf_counter()
    flag = lib.lcg_cvsens_solve(fns.table, fns.rhs, fns.out, fb("double[]", p_ext), ns, fb("int[]", which),
                                fb("double[]", y0), fb("double[]", np.ascontiguousarray(s0)), nt, fb("double[]", t),
                                fb("double[]", yout), fb("double[]", sout), fb("double[]", out), fb("double[]", dout),
                                opt, st)
    wall = time.perf_counter() - start
    if flag == CANCELLED:
        raise_pending()  # Ctrl-C during the run: KeyboardInterrupt
    res = driver_result(sim, ffi, st, flag, wall, method, names, t, yout, sout, out, dout)
    res.stats.update(alpha=alpha, beta=beta, projection=projection)
    res.events = []
    return res

