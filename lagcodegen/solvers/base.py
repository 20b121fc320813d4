"""What every solver family shares: the methods, one tolerance check, one table of flag
messages, one statistics record of the native drivers, the option structs they take, and the
initial state of an ODE run."""

from __future__ import annotations

import math
import operator
import struct
from collections.abc import Mapping

import numpy as np

from ..codegen.signatures import STAT_NAMES as SIGNATURE_STAT_NAMES
from ..codes import SOLVER_FLAG_TEXT, ModelCode
from ..errors import LagcodegenError, SingularMassMatrixError
from ..model.events import records
from ..util import check_finite, state_values

#: Linear multistep methods of CVODE (the values of CV_ADAMS, CV_BDF).
METHODS = {"adams": 1, "bdf": 2}
LINEAR_SOLVERS = ("dense", "band", "fixedpoint")
#: Error codes the generated model functions return (every language, every formulation;
#: :class:`lagcodegen.codes.ModelCode`).
ERR_SINGULAR, ERR_NONFINITE, ERR_PROJECTION = int(ModelCode.SINGULAR), int(ModelCode.NONFINITE), int(ModelCode.PROJECTION)

#: What a negative return flag of each solver family means (:data:`lagcodegen.codes.SOLVER_FLAG_TEXT`).
FLAG_TEXT = SOLVER_FLAG_TEXT
#: Kept under its earlier name.
CVODE_FLAG_TEXT = FLAG_TEXT["CVODE"]
SINGULAR_MASS = "the mass matrix is singular"
SINGULAR_AUGMENTED = ("the augmented matrix [M A^T; A 0] is singular (M singular or the constraint Jacobian A "
                      "rank deficient)")


def message(flag: int, model_error: int, detail: str, solver: str = "CVODE", singular: str = SINGULAR_MASS,
            t: float | None = None) -> str:
    """The message of a run that ended with ``flag``: success, the model's own error (singular
    matrix, non-finite value, at ``t`` if given) or the solver's, with the solver's ``detail`` text."""
    if flag >= 0:
        return "success"
    if model_error == ERR_SINGULAR:
        return singular
    if model_error == ERR_NONFINITE:
        return "a computed value is not finite" + (f" at t = {t:.17g}" if t is not None else "")
    text = FLAG_TEXT.get(solver, {}).get(flag, f"{solver} failed with flag {flag}")
    return f"{text}: {detail}" if detail else text


_ZERO_TOLERANCES = ("rtol and atol are both 0: no error tolerance at all (the solver's error weights "
                    "1/(rtol |y| + atol) would divide by zero); give rtol > 0 or atol > 0")


def tolerances(rtol, atol, size: int, n_diff: int | None = None, scalar: bool = False):
    """(rtol, atol as one value per state): ``atol`` a scalar, one value per state, or one per
    differential state (``n_diff``; the algebraic ones get the smallest). Both finite, >= 0.
    With ``scalar``, a scalar ``atol`` is returned as a float (the runners take either)."""
    rtol = check_finite(rtol, "rtol")
    if type(atol) is float or type(atol) is int:  # the common case, without numpy reductions
        if not (math.isfinite(atol) and atol >= 0 and rtol >= 0):
            raise LagcodegenError("tolerances must be finite and non-negative")
        if rtol == 0 and atol == 0:
            raise LagcodegenError(_ZERO_TOLERANCES)
        return rtol, (float(atol) if scalar else np.full(size, float(atol)))
    try:
        arr = np.asarray(atol, dtype=float).ravel()
    except (TypeError, ValueError):
        raise LagcodegenError(f"atol must be a number or an array of numbers, got {atol!r:.60}") from None
    if arr.size == 1:
        out = np.full(size, float(arr[0]))
    elif n_diff is not None and arr.size == n_diff and n_diff != size:
        out = np.concatenate([arr, np.full(size - n_diff, float(np.min(arr)))])
    elif arr.size == size:
        out = arr.copy()
    else:
        raise LagcodegenError(f"atol has {arr.size} values, expected 1 or {n_diff or size}")
    if not np.all(np.isfinite(out)) or np.any(out < 0) or rtol < 0:
        raise LagcodegenError("tolerances must be finite and non-negative")
    if rtol == 0 and not np.all(out > 0):
        zero = np.flatnonzero(out == 0)
        raise LagcodegenError(_ZERO_TOLERANCES + f" (atol is 0 for state {', '.join(map(str, zero[:8]))}"
                              + (", ..." if zero.size > 8 else "") + ")")
    return rtol, out


#: Fields of the native drivers' statistics structs -> keys of Result.stats (from the structs'
#: declaration, :data:`lagcodegen.codegen.signatures.STAT_FIELDS`).
STAT_NAMES = SIGNATURE_STAT_NAMES


_FIELDS: dict = {}


_CODES = {("int", 4): "i", ("long", 8): "q", ("long", 4): "i", ("double", 8): "d"}


def _stats_reader(ffi, ctype):
    """(keys, a getter of the counters and of nrhs, nrhs_dq / nres, nres_dq where present, which
    of those two pairs are there) for a statistics struct type. The getter reads every field in
    one ``struct.unpack_from`` of the struct's bytes (offsets and sizes from cffi)."""
    fields = dict(ctype.item.fields)
    names = [name for name in STAT_NAMES if name in fields]
    keys = [STAT_NAMES[name] for name in names]
    rhs, res = "nrhs" in fields, "nres" in fields
    names += ["nrhs", "nrhs_dq"] * rhs + ["nres", "nres_dq"] * res
    layout = sorted((fields[name].offset, i, name) for i, name in enumerate(names))
    fmt, pos, order = "=", 0, [0] * len(names)
    for k, (offset, i, name) in enumerate(layout):
        ftype = fields[name].type
        code = _CODES.get((ftype.cname, ffi.sizeof(ftype)))
        if code is None or offset < pos:
            return keys, operator.attrgetter(*names) if len(names) > 1 else (lambda st: (getattr(st, names[0]),)), \
                rhs, res
        fmt += f"{offset - pos}x" * (offset > pos) + code
        pos = offset + ffi.sizeof(ftype)
        order[i] = k
    unpack = struct.Struct(fmt).unpack_from
    buffer = ffi.buffer
    if order == sorted(order):
        return keys, (lambda st: unpack(buffer(st))), rhs, res
    pick = operator.itemgetter(*order)
    return keys, (lambda st: pick(unpack(buffer(st)))), rhs, res


def native_stats(ffi, st) -> dict:
    """Result.stats from a native driver's statistics struct (CVODE, index-1 CVODE, IDA): every
    counter it has, by the names of :data:`STAT_NAMES`, and the right-hand-side (or residual)
    evaluations including those of difference-quotient Jacobians."""
    ctype = ffi.typeof(st)
    reader = _FIELDS.get(ctype)
    if reader is None:
        reader = _FIELDS[ctype] = _stats_reader(ffi, ctype)
    keys, get, rhs, res = reader
    values = get(st)  # every field in one call
    stats = dict(zip(keys, values))
    k = len(keys)
    if rhs:
        stats["rhs_evals"] = values[k] + values[k + 1]
        stats["rhs_evals_dq"] = values[k + 1]
        k += 2
    if res:
        stats["rhs_evals"] = values[k] + values[k + 1]
        stats["res_evals"] = values[k]
        stats["res_evals_dq"] = values[k + 1]
    return stats


def native_options(ffi, typename: str, atol: np.ndarray, keep: list, **values):
    """A native driver's options struct: every field from ``values``; ``atol`` (a float, or an
    array) as the scalar ``atol`` when all entries are equal, else also as ``atol_vec`` (its
    buffer appended to ``keep`` so that it outlives the call)."""
    opt = ffi.new(f"{typename} *")
    if type(atol) is float:
        opt.atol = atol
        opt.atol_vec = ffi.NULL
    elif np.any(atol != atol[0]):
        opt.atol = float(atol[0])
        keep.append(atol)
        opt.atol_vec = ffi.from_buffer("double[]", atol)
    else:
        opt.atol = float(atol[0])
        opt.atol_vec = ffi.NULL
    for name, value in values.items():
        setattr(opt, name, value)
    return opt


class PreparedOptions:
    """The options structs of one native driver kept for reuse across calls (per compiled module):
    one struct per distinct set of values, compared bit for bit (the values packed with
    ``formats``, and the bytes of ``atol``), never written once made, so that concurrent runs
    may share it. ``fixed``: fields with the same value in every struct."""

    LIMIT = 64  # structs kept at most (then the cache starts afresh)

    def __init__(self, ffi, typename: str, names: tuple, formats: str, **fixed):
        self.ffi, self.typename, self.names, self.fixed = ffi, typename, names, fixed
        self._pack = struct.Struct("=" + formats).pack
        self._cache: dict = {}
        self._last = None  # (atol, values, struct) of the last call (float atol or a read-only array)

    def get(self, atol, *values):
        """The struct of ``native_options(ffi, typename, atol, ..., **fixed, **dict(zip(names, values)))``."""
        last = self._last
        if last is not None and (last[0] is atol or (type(atol) is float and type(last[0]) is float
                                                     and last[0] == atol)) and last[1] == values:
            return last[2]  # the same values as the last call (equal numbers: the same C behaviour)
        try:
            key = (b"f" + _DOUBLE(atol) if type(atol) is float else b"a" + atol.tobytes()) + self._pack(*values)
        except (struct.error, TypeError, ValueError, OverflowError, AttributeError):
            key = None  # values a struct cannot hold bit for bit: a new struct (which says what is wrong)
        entry = self._cache.get(key) if key is not None else None
        if entry is None:
            keep: list = []
            if key is not None and type(atol) is not float:
                atol = atol.copy()  # the struct's own (its atol_vec points into it)
            opt = native_options(self.ffi, self.typename, atol, keep, **self.fixed, **dict(zip(self.names, values)))
            if key is None:
                return opt
            if len(self._cache) >= self.LIMIT:
                self._cache.clear()
            entry = self._cache[key] = (opt, keep)
        if all(v == v for v in values) and (type(atol) is float and atol == atol
                                            or type(atol) is np.ndarray and not atol.flags.writeable):
            # no NaN, so that equality holds; an array atol only by identity, and read-only (the
            # callers' cached tolerance arrays): its values cannot have changed
            self._last = (atol, values, entry[0])
        return entry[0]


_DOUBLE = struct.Struct("=d").pack


def pooled_stats(ffi, pool: list, typename: str):
    """A statistics struct of a finished run from ``pool`` (the drivers clear it first), else a
    new ``typename``; the caller appends it back once read."""
    try:
        return pool.pop()
    except IndexError:
        return ffi.new(typename)


def reached_rows(t, yout, out, done: int):
    """(t, y, outputs) of a run that filled ``done`` rows: copies of those rows when it stopped
    early, else the driver's arrays themselves (``t`` copied: callers may reuse their grid)."""
    if done < t.size:
        return t[:done].copy(), yout[:done].copy(), out[:done].copy()
    return t.copy(), yout, out


def file_initial(sim, q0, v0) -> tuple:
    """``q0``, ``v0`` with the defaults of a system compiled from a model file
    (:func:`lagcodegen.compile_file` sets ``sim.initial_defaults`` to the file's
    ``[simulation] initial``): each one not given (None) is the file's; unchanged for any other
    compiled system (None: zeros, or required where a run requires it)."""
    defaults = getattr(sim, "initial_defaults", None)
    if defaults is None:
        return q0, v0
    return (list(defaults[0]) if q0 is None else q0), (list(defaults[1]) if v0 is None else v0)


def initial_state(cm, q0, v0, y0, z0=None) -> np.ndarray:
    """The state y = (q, q', z) of an ODE run from q0/v0 (and z0) or the whole y0; q0, v0 not
    given are the model file's initial values for a model compiled from one (:func:`file_initial`)."""
    n = cm.n
    if y0 is not None:
        if q0 is not None or v0 is not None or z0 is not None:
            raise LagcodegenError("give either y0 or q0/v0, not both")
        try:
            y = np.array(y0, dtype=float).ravel()
        except (TypeError, ValueError):
            raise LagcodegenError(f"y0 must be an array of {cm.ny} numbers, got {y0!r:.60}") from None
        if y.size != cm.ny:
            raise LagcodegenError(f"y0 has {y.size} values, the state has {cm.ny}: {', '.join(cm.state_names)}")
        return y
    names = cm.state_names
    nv = getattr(cm.code, "speeds", n)
    q0, v0 = file_initial(cm, q0, v0)
    neutral = getattr(cm.code, "q_neutral", None)
    if neutral is not None and (q0 is None or isinstance(q0, Mapping)):  # quaternions: the identity
        q0 = {**dict(zip(names[:n], neutral)), **(q0 or {})}
    # velocities by coordinate name; generalized speeds by their own names
    speed_names = names[:n] if getattr(cm.code, "nv", None) is None else names[n:n + nv]
    return np.array(state_values(q0, names[:n], "q0") + state_values(v0, speed_names, "v0")
                    + state_values(z0, names[n + nv:], "z0"), dtype=float)


def check_initial_mass_matrix(cm, t0: float, y: np.ndarray, p: np.ndarray) -> None:
    """Raise SingularMassMatrixError naming the state if M is singular at (t0, y)."""
    try:
        cm.rhs(t0, y, p)
    except SingularMassMatrixError as exc:
        raise SingularMassMatrixError(
            "the mass matrix is singular at the initial state "
            f"({', '.join(f'{k}={v:g}' for k, v in zip(cm.state_names, y))})", t=float(t0)) from exc


class NativeEvents:
    """The events struct a native driver with root finding fills (``typename``, e.g. the
    constrained drivers' ``lcg_events``), its buffers, and the :class:`EventRecord` s made from it."""

    def __init__(self, ffi, typename: str, events: list, ny: int, max_events: int):
        self.events = events
        self.ny = ny
        self.max_events = max_events
        self.t = np.full(max_events, np.nan)
        self.y = np.full((max_events, ny), np.nan)
        self.which = np.zeros(max_events, dtype=np.intc)
        self.direction = np.zeros(max_events, dtype=np.intc)
        self.rootdir = np.array([e.direction for e in events], dtype=np.intc)
        self.terminal = np.array([1 if e.terminal else 0 for e in events], dtype=np.intc)
        ev = self.struct = ffi.new(f"{typename} *")
        ev.max_events = max_events
        ev.t = ffi.from_buffer("double[]", self.t)
        ev.y = ffi.from_buffer("double[]", self.y)
        ev.which = ffi.from_buffer("int[]", self.which)
        ev.direction = ffi.from_buffer("int[]", self.direction)
        ev.rootdir = ffi.from_buffer("int[]", self.rootdir)
        ev.terminal = ffi.from_buffer("int[]", self.terminal)

    @property
    def count(self) -> int:
        return min(int(self.struct.n_events), len(self.t))

    @property
    def terminated(self) -> bool:
        return bool(self.struct.terminated)

    def records(self, state_names: list, n_state: int) -> list:
        k = self.count
        return records(self.events, self.t[:k], self.y[:k], self.which[:k], self.direction[:k], state_names,
                       n_state)
