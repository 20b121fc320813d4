"""The Python side of a runtime stepper (lagcodegen/runtime/lcg_<kind>_stepper.c, the C state of
an integrator object) that the families' steppers share: the handle a ``lcg_<kind>_stepper_new``
call returns, checked, with its statistics and calls bound; freed once; the events of the last
call, its statistics under the names of the runs' Result.stats; the absolute tolerance option of
one or ``n`` values."""

from __future__ import annotations

import functools

import numpy as np

from ..errors import LagcodegenError
from .base import native_stats


def tolerance_option(ffi, opt, atol, n: int):
    """``opt.atol`` and ``opt.atol_vec`` of a driver's options from ``atol``: a float (no vector),
    or ``n`` values (broadcast; ``opt.atol`` their minimum). Returns the array ``opt.atol_vec``
    points into (None for a float), to be kept until the stepper has copied it."""
    if isinstance(atol, float):
        opt.atol, opt.atol_vec = atol, ffi.NULL
        return None
    keep = np.ascontiguousarray(np.broadcast_to(np.asarray(atol, dtype=float), (n,)))
    opt.atol = float(keep.min())
    opt.atol_vec = ffi.from_buffer("double[]", keep)
    return keep


class NativeStepper:
    """A stepper of the runtime module ``self.lib`` (``self.ffi``) named ``kind``
    (``lcg_<kind>_stepper_*``); a family's stepper sets ``ffi``, ``lib`` and its events record
    ``_native`` (:class:`~.base.NativeEvents`-like, or None) and calls :meth:`_bind` with what
    ``lcg_<kind>_stepper_new`` returned."""

    kind = ""
    #: The stepper's calls bound as attributes of the same names (lcg_<kind>_stepper_<call>).
    calls = ("until", "grid", "step")
    handle = None
    _native = None

    def _bind(self, handle, message, what: str) -> None:
        """Keep ``handle``, with its statistics and :attr:`calls` bound; a NULL handle is the
        ``LagcodegenError`` "<what>: <the stepper's message>" (``message``: its char[] buffer)."""
        ffi, lib = self.ffi, self.lib
        if handle == ffi.NULL:
            raise LagcodegenError(f"{what}: {ffi.string(message).decode(errors='replace')}")
        self.handle = handle
        self.stats = getattr(lib, f"lcg_{self.kind}_stepper_stats")(handle)
        for call in self.calls:
            setattr(self, call, functools.partial(getattr(lib, f"lcg_{self.kind}_stepper_{call}"), handle))

    def stats_dict(self) -> dict:
        """The last call's statistics, by the keys of a run's Result.stats
        (:func:`~.base.native_stats`)."""
        return native_stats(self.ffi, self.stats)

    def _release(self) -> None:
        """What the family drops before the C stepper is freed (views of its memory)."""

    def free(self) -> None:
        """Free the C stepper (once)."""
        handle, self.handle = self.handle, None
        if handle is not None:
            self._release()
            getattr(self.lib, f"lcg_{self.kind}_stepper_free")(handle)

    def event_arrays(self):
        """(count, terminated, (t, y, which, direction)) of the last call's events."""
        ev = self._native
        return int(ev.struct.n_events), ev.terminated, (ev.t, ev.y, ev.which, ev.direction)
