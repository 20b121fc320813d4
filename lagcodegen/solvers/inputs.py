"""Input signals from tables: :class:`Table` (a signal u(t) given at breakpoints, held, linearly
interpolated or splined, as one piecewise cubic), the check of ``simulate(..., inputs=...)``
against a compiled model's inputs (:func:`input_set`), and the packing of the tables into the
``lcg_inputs`` struct the runtime's drivers read (``lagcodegen/runtime/lcg_inputs.h``), where the
value is computed in C at every evaluation time of the right-hand side and the Jacobian.

An input is a run-time parameter of the model (``Model.input``): a table sets that parameter's
slot at each evaluation time. Piece layout (the one of lcg_inputs.h): with breakpoints
t_0 < ... < t_(n-1), piece 0 holds u(t_0) before t_0, piece k (0 < k < n) is the cubic of
[t_(k-1), t_k) in s = t - t_(k-1), piece n holds u(t_(n-1)) from t_(n-1) on; every piece is
right-continuous at its start (a zero-order hold takes the new value at its breakpoint). The
drivers stop and restart at the run's restart times (:meth:`Table.restart_times`: by default the
breakpoints where u or its slope jumps), so that no step straddles a jump or a kink.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ..errors import LagcodegenError

#: The interpolation kinds of a table.
KINDS = ("zoh", "linear", "cubic")
#: End conditions of a cubic table (scipy.interpolate.CubicSpline's bc_type): not-a-knot (C2
#: and C3 at the second and second-to-last breakpoints) or natural (zero second derivative).
CUBIC_ENDS = ("not-a-knot", "natural")


class Table:
    """A signal u(t) given at breakpoints ``times`` (finite, strictly increasing) with ``values``
    (finite, one per time).

    ``kind``: "zoh" (zero-order hold: u = values[i] on [times[i], times[i+1])), "linear"
    (default) or "cubic" (a C2 cubic spline through the points, computed once here, with the
    ``ends`` condition "not-a-knot" or "natural"). Before the first time and after the last the
    signal holds its end value.

    ``restart``: where the integrator stops and starts afresh (CVODE: CVodeReInit), so that no step
    straddles a jump or a kink of u (each costs a cascade of rejected steps otherwise): "auto"
    (default) at the breakpoints where u or du/dt jumps (a zero-order hold where the value
    changes; a linear table at its kinks; a cubic spline only at its ends, where it meets the held
    end values); True at every breakpoint; False nowhere (the steps straddle the breakpoints).
    For a smooth signal sampled finely a cubic table runs much faster than a linear one, whose
    every sample is a kink and a restart.
    """

    def __init__(self, times, values, *, kind: str = "linear", ends: str = "not-a-knot",
                 restart: bool | str = "auto", name: str = "table"):
        if kind not in KINDS:
            raise LagcodegenError(f"{name}: kind must be one of {', '.join(KINDS)}, got {kind!r}")
        if ends not in CUBIC_ENDS:
            raise LagcodegenError(f"{name}: ends must be one of {', '.join(CUBIC_ENDS)}, got {ends!r}")
        if not (isinstance(restart, bool) or restart == "auto"):
            raise LagcodegenError(f"{name}: restart must be 'auto', True or False, got {restart!r}")
        t = _vector(times, f"{name}: times")
        v = _vector(values, f"{name}: values")
        if t.size != v.size:
            raise LagcodegenError(f"{name}: {t.size} times but {v.size} values (one value per time)")
        if t.size < 1:
            raise LagcodegenError(f"{name}: the table is empty (give at least one time and value)")
        if t.size > 1 and not (np.diff(t) > 0).all():
            i = int(np.argmax(~(np.diff(t) > 0)))
            raise LagcodegenError(f"{name}: times must increase strictly, but times[{i}] = {t[i]!r} and "
                                  f"times[{i + 1}] = {t[i + 1]!r}")
        if kind == "cubic" and t.size < 2:
            raise LagcodegenError(f"{name}: a cubic table needs at least 2 points, got {t.size}")
        self.times, self.values, self.kind, self.ends, self.restart = t, v, kind, ends, restart
        self.coefficients = _pieces(t, v, kind, ends)  # (n + 1, 4), lowest power first
        self.coefficients.setflags(write=False)
        t.setflags(write=False)
        v.setflags(write=False)

    def __repr__(self) -> str:
        return (f"Table({self.times.size} points on [{self.times[0]:g}, {self.times[-1]:g}], kind={self.kind!r}"
                f"{f', restart={self.restart!r}' if self.restart != 'auto' else ''})")

    def restart_times(self) -> np.ndarray:
        """The breakpoints where a run stops and restarts (see ``restart``)."""
        if self.restart is False:
            return self.times[:0]
        if self.restart is True:
            return self.times
        t = self.times
        scale = max(1.0, float(np.abs(self.values).max()))
        left_v, right_v = self._ends(t, 0), self.coefficients[1:, 0]
        left_d, right_d = self._ends(t, 1), self.coefficients[1:, 1]
        tol = 64 * np.finfo(float).eps * scale
        span = max(float(t[-1] - t[0]), 1.0)
        jump = (np.abs(left_v - right_v) > tol) | (np.abs(left_d - right_d) * span > tol)
        return t[jump]

    def _ends(self, t: np.ndarray, order: int) -> np.ndarray:
        """The value (``order`` 0) or slope (1) at each breakpoint of the piece that ends there."""
        c = self.coefficients[:-1]
        s = np.concatenate([[0.0], np.diff(t)])  # piece 0 is constant; piece k ends h_(k-1) after its origin
        if order == 0:
            return c[:, 0] + s * (c[:, 1] + s * (c[:, 2] + s * c[:, 3]))
        return c[:, 1] + s * (2 * c[:, 2] + 3 * s * c[:, 3])

    def piece(self, t) -> np.ndarray:
        """The piece holding each of ``t``: the number of breakpoints <= t (0 .. n)."""
        return np.searchsorted(self.times, np.asarray(t, dtype=float), side="right")

    def __call__(self, t) -> np.ndarray | float:
        """u(t) (an array for an array of times), as the drivers compute it."""
        tt = np.asarray(t, dtype=float)
        k = self.piece(tt)
        origin = self.times[np.clip(k - 1, 0, self.times.size - 1)]
        s = tt - origin
        c = self.coefficients[k]
        out = c[..., 0] + s * (c[..., 1] + s * (c[..., 2] + s * c[..., 3]))
        return float(out) if np.ndim(t) == 0 else out

    def derivative(self, t, order: int = 1) -> np.ndarray | float:
        """The ``order``-th time derivative of u at ``t`` on the piece that holds t."""
        tt = np.asarray(t, dtype=float)
        k = self.piece(tt)
        s = tt - self.times[np.clip(k - 1, 0, self.times.size - 1)]
        c = self.coefficients[k]
        out = np.zeros_like(s)
        for j in range(order, 4):
            out = out + math.perm(j, order) * c[..., j] * s ** (j - order)
        return float(out) if np.ndim(t) == 0 else out


def _vector(x, what: str) -> np.ndarray:
    try:
        arr = np.array(x, dtype=float).reshape(-1) if np.ndim(x) <= 1 else None
    except (TypeError, ValueError):
        raise LagcodegenError(f"{what} must be numbers") from None
    if arr is None:
        raise LagcodegenError(f"{what} must be one-dimensional, got shape {np.shape(x)}")
    if not np.isfinite(arr).all():
        i = int(np.argmax(~np.isfinite(arr)))
        raise LagcodegenError(f"{what}[{i}] is not finite ({arr[i]!r})")
    return np.ascontiguousarray(arr)


def _pieces(t: np.ndarray, v: np.ndarray, kind: str, ends: str) -> np.ndarray:
    n = t.size
    c = np.zeros((n + 1, 4))
    c[0, 0] = v[0]
    c[n, 0] = v[-1]
    if n == 1:
        return c
    h = np.diff(t)
    if kind == "zoh":
        c[1:n, 0] = v[:-1]
    elif kind == "linear":
        c[1:n, 0] = v[:-1]
        c[1:n, 1] = np.diff(v) / h
    else:
        from scipy.interpolate import CubicSpline
        spline = CubicSpline(t, v, bc_type=ends)
        c[1:n, :] = spline.c[::-1].T  # scipy: highest power first, in s = t - t_i
    return c


# ---------------------------------------------------------------------- a run's inputs
class InputSet:
    """The tables of one run, by the slot of the run-time parameter each sets: ``slots``,
    ``names``, ``tables`` (parallel lists); ``restarts`` the restart times of them all."""

    def __init__(self, slots: list[int], names: list[str], tables: list[Table]):
        self.slots, self.names, self.tables = slots, names, tables
        self.restarts = np.unique(np.concatenate([tab.restart_times() for tab in tables]))

    def __bool__(self) -> bool:
        return bool(self.tables)

    def restarts_in(self, t0: float, t1: float) -> np.ndarray:
        """The restart times in (t0, t1)."""
        r = self.restarts
        return r[(r > t0) & (r < t1)]

    def apply(self, p: np.ndarray, t: float) -> np.ndarray:
        """A copy of ``p`` with each input's slot at its value at ``t``."""
        p = np.array(p, dtype=float)
        for slot, tab in zip(self.slots, self.tables):
            p[slot] = tab(float(t))
        return p

    def struct(self, ffi, keep: list):
        """The ``lcg_inputs *`` of these tables (its arrays appended to ``keep``)."""
        s = ffi.new("lcg_inputs *")
        keep.append(s)
        self.fill(ffi, s, keep)
        return s

    def fill(self, ffi, s, keep: list) -> None:
        """Fill the ``lcg_inputs`` ``s`` with these tables (arrays appended to ``keep``)."""
        tabs = ffi.new("lcg_input_table[]", len(self.tables))
        keep.append(tabs)
        for k, (slot, tab) in enumerate(zip(self.slots, self.tables)):
            coef = np.ascontiguousarray(tab.coefficients.reshape(-1))
            keep.append(coef)
            tabs[k].slot = slot
            tabs[k].n = tab.times.size
            tabs[k].t = ffi.from_buffer("double[]", tab.times)
            tabs[k].c = ffi.from_buffer("double[]", coef)
            keep.extend([tabs[k].t, tabs[k].c])
        s.count = len(self.tables)
        s.tables = tabs
        s.nbreak = self.restarts.size
        if self.restarts.size:
            s.breaks = ffi.from_buffer("double[]", self.restarts)
            keep.append(s.breaks)


def fill_inputs(ffi, sets: list, keep: list):
    """An ``lcg_inputs[]`` array of the input sets ``sets`` (one per ensemble member)."""
    arr = ffi.new("lcg_inputs[]", len(sets))
    keep.append(arr)
    for k, one in enumerate(sets):
        one.fill(ffi, arr[k], keep)
    return arr


def as_table(name: str, spec) -> Table:
    """``spec`` (a :class:`Table` or a pair (times, values): linear) as the table of input ``name``."""
    if isinstance(spec, Table):
        return spec
    if isinstance(spec, (tuple, list)) and len(spec) == 2:
        return Table(spec[0], spec[1], name=f"input {name!r}")
    raise LagcodegenError(f"input {name!r}: expected lagcodegen.Table(times, values, kind=...) or a pair "
                          f"(times, values), got {type(spec).__name__}")


def _refuse_both(inputs: Mapping, params) -> None:
    """LagcodegenError naming the names that ``params`` gives a value and ``inputs`` a table."""
    both = [name for name in inputs if isinstance(params, Mapping) and name in params]
    if both:
        raise LagcodegenError(f"{', '.join(map(repr, both))} given both a value (params=) and a table (inputs=); "
                              "give each in one of them (the table drives the input over the run)")


def input_set(input_names: list[str], param_names: list[str], inputs: Mapping | None,
              model_name: str = "", *, params: Mapping | None = None) -> InputSet | None:
    """The tables of ``inputs`` (input name -> :class:`Table` or (times, values)) checked against a
    compiled model's inputs (``input_names``) and run-time parameters (``param_names``); None
    when ``inputs`` is empty. A name given a value in ``params`` (the run's parameter values) as
    well as a table is refused: one of the two would be ignored."""
    if inputs is None:
        return None
    if not isinstance(inputs, Mapping):
        raise LagcodegenError(f"inputs must be a mapping input name -> Table or (times, values), got "
                              f"{type(inputs).__name__}")
    if not inputs:
        return None
    _refuse_both(inputs, params)
    of = f" of model {model_name!r}" if model_name else ""
    if not input_names:
        raise LagcodegenError(f"inputs given ({', '.join(map(repr, inputs))}) but the model{of} declares no inputs "
                              "(Model.input or [inputs] in a model file)")
    slots, names, tables = [], [], []
    for name, spec in inputs.items():
        if name not in input_names:
            raise LagcodegenError(f"{name!r} is not an input{of} (its inputs: {', '.join(input_names)})")
        if name not in param_names:
            raise LagcodegenError(f"input {name!r} is folded into the code as a constant (the scene's "
                                  "runtime_parameters leave it out), so a table cannot drive it")
        slots.append(param_names.index(name))
        names.append(name)
        tables.append(as_table(name, spec))
    return InputSet(slots, names, tables)


def member_sets(input_names, param_names, inputs, n: int, model_name: str = "", *,
                params: Mapping | None = None) -> list[InputSet] | None:
    """The tables of the ``n`` members of an ensemble: ``inputs`` maps each input name to one table
    (shared) or a list of ``n`` tables (one per member: each a Table or a tuple (times, values)).
    ``params``: the ensemble's parameter values (a name in both refused, as by :func:`input_set`)."""
    if inputs is None or (isinstance(inputs, Mapping) and not inputs):
        return None
    if isinstance(inputs, Mapping):
        _refuse_both(inputs, params)
    if not isinstance(inputs, Mapping):
        raise LagcodegenError("inputs must be a mapping input name -> Table, (times, values) or a list of one per "
                              "member")
    per = {}
    for name, spec in inputs.items():
        if isinstance(spec, (list, tuple)) and spec and all(isinstance(x, (Table, tuple)) for x in spec):
            if len(spec) != n:
                raise LagcodegenError(f"input {name!r}: {len(spec)} tables for {n} members")
            per[name] = [as_table(name, s) for s in spec]
        else:
            per[name] = [as_table(name, spec)] * n
    return [input_set(input_names, param_names, {name: tabs[i] for name, tabs in per.items()}, model_name)
            for i in range(n)]
