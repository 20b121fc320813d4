"""The fast path of ``simulate()`` on a compiled scene (:class:`FastRuns`): a call with the same
option values as an earlier one (solver, rtol, atol and the other keywords, their types included)
goes from ``simulate()`` straight to a run its family prepared once (the options resolved and
checked, the driver's options struct made: ``prepared_ode`` of
:class:`~lagcodegen.solvers.taylor.Taylor` and :class:`~lagcodegen.solvers.cvode.CVODE`,
both with forward sensitivities too, their directions parsed once; with events,
``prepared_ode_events`` of the Taylor family), and returns a
:class:`~lagcodegen.solvers.lazy_result.LazyResult`.

What the call brings anew is checked as on the full path, with the same errors: the output
times, the initial state (length, dtype, finiteness) and the parameters. Runs with input tables,
runs with events on CVODE or with sensitivities, and options the families do not prepare
(scikit-sundae, array tolerances), take the full path. A list of names
(``sensitivities=[...]``) is kept for by its names and its type (a list and a tuple of the same
names prepare a run each). Both paths call the same C driver with
the same options and arrays, so their results are bit-identical; a failed run ends in the same
checks and errors (:func:`finish_run`, shared by both)."""

from __future__ import annotations

import math
import operator

import numpy as np

from ..errors import LagcodegenError, SingularMassMatrixError, SolverError
from ..formulation.drawing import deferred_drawing
from ..result import Result
from ..solvers.base import check_initial_mass_matrix, initial_state, tolerances
from ..solvers.family import Problem, Request
from ..solvers.registry import resolve
from ..util import output_times

_F64 = np.dtype(np.float64)
_NDARRAY = np.ndarray
_ISFINITE = math.isfinite
_LT = operator.lt
#: Types of option values a prepared run is kept for (hashable, compared by value).
_SCALARS = frozenset((str, int, float, bool, type(None)))
#: Types of rtol and atol a prepared run is kept for (array tolerances take the full path).
_TOLERANCES = frozenset((float, int))


def finish_run(cm, res: Result, t0: float, y: np.ndarray, p: np.ndarray, raise_on_error: bool) -> Result:
    """The end of every ODE run of ``cm`` (both paths): a run that failed at its start says which
    value it was (an output not finite, a singular mass matrix); with ``raise_on_error`` a failed
    run raises SolverError (SingularMassMatrixError) holding the result."""
    if res.success:
        return res
    if res.t.size <= 1:  # failed at the start: say which value it was
        cm.check_initial_outputs(t0, y, p)
        if res.stats.get("model_error") == 1:
            check_initial_mass_matrix(cm, t0, y, p)
    if raise_on_error:
        cls = SingularMassMatrixError if res.stats.get("model_error") == 1 else SolverError
        raise cls(res.message, t=res.stats.get("t_reached", res.t[-1] if res.t.size else t0), flag=res.status,
                  result=res)
    return res


def _names(value) -> bool:
    """A list or tuple of names (e.g. ``sensitivities``): kept for by its tuple of names."""
    return type(value) in (list, tuple) and all(type(x) is str for x in value)


def _names_key(solver, rtol, atol, options: dict):
    """The key of a call whose option values are scalars or lists or tuples of names, else None:
    the values as they are where they hash, a list of names as (list, its tuple), so that a list
    and a tuple of the same names have keys of their own."""
    key = (solver, rtol, atol, *options.items())
    try:
        hash(key)
        return key
    except TypeError:
        pass
    if type(rtol) not in _TOLERANCES or type(atol) not in _TOLERANCES:
        return None  # array tolerances: the full path
    items = []
    for k, v in options.items():
        if type(v) is list and _names(v):
            v = (list, tuple(v))
        elif type(v) not in _SCALARS and not _names(v):
            return None
        items.append((k, v))
    return (solver, rtol, atol, *items)


class FastRun:
    """One prepared run of a compiled scene and the per-call checks of what a call brings anew.

    ``rtol_type``, ``atol_type`` and ``checks`` ((keyword, type) of each option value that is not
    a string) are the types the call's values must have beside being equal to the key's: values
    equal across types (2 and 2.0, 1 and True) may resolve differently."""

    __slots__ = ("run", "rtol_type", "atol_type", "checks", "ny", "p", "p_ptr", "ffi", "last")

    def __init__(self, cm, run, rtol, atol, options: dict):
        self.run = run
        self.rtol_type, self.atol_type = type(rtol), type(atol)
        self.checks = tuple((k, type(v)) for k, v in options.items() if type(v) is not str)
        self.ny = cm.ny
        p = cm.parameter_vector(None)
        p.flags.writeable = False  # the default parameters every run without ``params`` shares
        self.p = p
        self.p_ptr = cm.c_params(p)
        self.ffi = cm.ffi
        # the last output times and initial state and their cdata: a caller passing the same arrays
        # again costs no conversion (the cdata holds its array: no other can take its address)
        self.last = ((None, None), (None, None))

    def __call__(self, cm, t, q0, v0, y0, z0, params, raise_on_error: bool) -> Result:
        if type(t) is _NDARRAY and t.dtype is _F64 and t.ndim == 1 and 2 <= t.size <= 64 and t.flags.c_contiguous:
            # the common few output times: output_times' check (finite ends, strictly increasing,
            # so every time finite), without its call; two or three times by comparisons alone
            times = t.tolist()
            a, b = times[0], times[-1]
            n = len(times)
            if not (a < b and _ISFINITE(a) and _ISFINITE(b)
                    and (n == 2 or (a < times[1] < b if n == 3 else all(map(_LT, times, times[1:]))))):
                output_times(t)  # raises its error
        else:
            t = output_times(t)
        if (type(y0) is _NDARRAY and q0 is None and v0 is None and z0 is None and y0.dtype is _F64
                and y0.shape == (self.ny,) and y0.flags.c_contiguous):
            y = y0  # read by the driver only (const), never kept: no copy
        else:
            y = initial_state(cm, q0, v0, y0, z0)
        # q0, v0, z0 were checked finite one by one (ModelError naming which); y0 as a whole here
        if y0 is not None and not all(map(_ISFINITE, y.tolist())):
            raise LagcodegenError("the initial state has non-finite values")
        if params is None:
            p, p_ptr = self.p, self.p_ptr
        else:
            p = cm.parameter_vector(params)
            p_ptr = cm.c_params(p)
        (t_last, t_ptr), (y_last, y_ptr) = self.last
        if t is not t_last or y is not y_last:
            fb = self.ffi.from_buffer
            t_ptr = t_ptr if t is t_last else fb("double[]", t)
            y_ptr = y_ptr if y is y_last else fb("double[]", y)
            self.last = ((t, t_ptr), (y, y_ptr))
        res = self.run(t, t_ptr, y_ptr, p, p_ptr)
        if res.status < 0:
            return finish_run(cm, res, t[0], y, p, raise_on_error)
        return res


def _same_types(run: "FastRun | None", rtol, atol, options: dict) -> "FastRun | None":
    """``run`` if this call's tolerances and options have the types it was prepared with, else None."""
    if run is None or type(rtol) is not run.rtol_type or type(atol) is not run.atol_type:
        return None
    for k, kind in run.checks:
        if type(options[k]) is not kind:
            return None
    return run


class FastRuns:
    """The prepared runs of one compiled scene, by the option values of the ``simulate()`` calls
    that made them (at most :attr:`LIMIT`; then the cache starts afresh)."""

    LIMIT = 64

    def __init__(self):
        self._runs: dict = {}

    def get(self, solver, rtol, atol, options: dict) -> FastRun | None:
        """The prepared run of a call with these values (of the same types), else None."""
        try:
            run = self._runs.get((solver, rtol, atol, *options.items()))
        except TypeError:  # lists of names (sensitivities) by their tuple; other unhashable values: the full path
            key = _names_key(solver, rtol, atol, options)
            if key is None:
                return None
            run = self._runs.get(key)
        return _same_types(run, rtol, atol, options)

    def get_events(self, solver, rtol, atol, options: dict, events) -> FastRun | None:
        """:meth:`get` of a call with ``events`` (compared by value, as the families key their
        compiled events); None where a value does not hash (that call takes the full path)."""
        try:
            run = self._runs.get((solver, rtol, atol, *options.items(), ("events", tuple(events))))
        except TypeError:
            return None
        return _same_types(run, rtol, atol, options)

    def learn(self, cm, solver, rtol, atol, options: dict, events=()) -> None:
        """After a call on the full path that did not raise: prepare its run for the next calls
        with these values, where the family prepares it (else remember that it does not). With
        ``events``: the family's ``prepared_ode_events``, a call of hashable option values only."""
        if not preparable(rtol, atol, options):
            return
        key = _names_key(solver, rtol, atol, options)
        if events:
            try:
                key = (*key, ("events", tuple(events)))
                hash(key)
            except TypeError:
                return
        if key in self._runs:
            return
        run = family_run(cm, solver, rtol, atol, options, events)
        if len(self._runs) >= self.LIMIT:
            self._runs.clear()
        self._runs[key] = None if run is None else FastRun(cm, run, rtol, atol, options)


def preparable(rtol, atol, options: dict) -> bool:
    """Whether a run of these values can be prepared: scalar tolerances, option values that are
    scalars or lists of names, no input tables (those runs take the full path)."""
    return (type(rtol) in _TOLERANCES and type(atol) in _TOLERANCES and options.get("inputs") is None
            and all(type(v) in _SCALARS or _names(v) for v in options.values()))


def family_run(cm, solver, rtol, atol, options: dict, events=()):
    """The run of ``cm`` that the family of ``solver`` and ``options`` prepares once for these
    tolerances (``prepared_ode``, with ``events`` ``prepared_ode_events``), or None where the
    family does not prepare it (those runs take the full path)."""
    rtol_f, atol_f = tolerances(rtol, atol, cm.ny, scalar=True)
    own = {k: v for k, v in options.items() if k != "inputs"}
    family = resolve("ode", solver, own, cm.method_size, rtol_f, costs=cm.method_costs)
    fixed = {"n_coordinates": cm.n, "n_speeds": cm.code.nv, "model_name": cm.code.model_name or "",
             "drawing": deferred_drawing(cm)}
    request = Request(kind="prepared", events=tuple(events), fixed=fixed)
    return family.run("ode", Problem(cm, rtol_f, atol_f), request) if family.supports("ode", request) else None
