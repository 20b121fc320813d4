"""Run control of the native drivers: Ctrl-C, progress and wall-clock limits (lagcodegen/runtime/lcg_control.h).

cffi releases the GIL around a driver call, so Python's SIGINT handler cannot run until the call
returns. Every driver therefore takes a poll callback (``lcg_poll``, an ``extern "Python"``
function of each compiled module) that it calls from the calling thread once a run has lasted
``POLL_EVERY`` seconds, and then every ``POLL_EVERY`` seconds: running Python bytecode there lets
the interpreter raise a pending KeyboardInterrupt, which the callback turns into "stop" (the
driver returns -80 within one poll interval plus 64 right-hand-side calls) and which the runner
raises again once the call has returned. A run shorter than ``POLL_EVERY`` never calls back: the
cost is one clock read per 64 right-hand-side calls.

Ensembles (:mod:`.ensemble`) pass a :class:`Progress` as the callback's data: the calling C thread
waits for its workers and calls back with the members done.
"""

from __future__ import annotations

import sys
import threading
import time

from ..codes import FLAG_TEXT as CODE_TEXT
from ..codes import Flag
from ..progress import StatusLine

#: Seconds between two calls of the poll callback (Ctrl-C latency, progress refresh).
POLL_EVERY = 0.05
#: Driver flags of run control (:class:`lagcodegen.codes.Flag`).
CANCELLED, TIMED_OUT, NOT_RUN, CHUNK_FAILED = (int(f) for f in (Flag.CANCELLED, Flag.TIMED_OUT, Flag.NOT_RUN,
                                                                  Flag.CHUNK_FAILED))
FLAG_TEXT = {flag: CODE_TEXT[flag] for flag in (CANCELLED, TIMED_OUT, NOT_RUN, CHUNK_FAILED)}

_pending = threading.local()


def _onerror(exc_type, exc_value, tb) -> None:
    """An exception inside the poll callback (KeyboardInterrupt from Ctrl-C, or an error of the
    progress display): kept for the runner, and the driver told to stop (the callback's error
    value is 1)."""
    _pending.error = exc_value


def install(module) -> object:
    """The poll callback of a compiled cffi ``module`` (defined once per module), or ffi.NULL if the
    module has none (built without the native drivers)."""
    ffi, lib = module.ffi, module.lib
    if not hasattr(lib, "lcg_poll"):
        return ffi.NULL
    if not getattr(module, "_lcg_poll_defined", False):
        null = ffi.NULL
        from_handle = ffi.from_handle

        @ffi.def_extern(name="lcg_poll", error=1, onerror=_onerror)
        def lcg_poll(data, done, total):
            if data != null:
                return from_handle(data).update(done, total)
            return 0

        module._lcg_poll_defined = True
    return lib.lcg_poll


def raise_pending() -> None:
    """After a driver returned -80: raise the exception its poll callback caught (KeyboardInterrupt
    from Ctrl-C), if any."""
    err = getattr(_pending, "error", None)
    if err is not None:
        _pending.error = None
        raise err


def take_pending():
    """The exception the poll callback caught (and forget it), or None."""
    err = getattr(_pending, "error", None)
    _pending.error = None
    return err


class Progress:
    """A progress line on stderr, refreshed by the poll callback: shown when ``show`` is True, or
    (``show`` None) once the run has lasted ``after`` seconds."""

    def __init__(self, total: int, show: bool | None = None, after: float = 2.0, label: str = "ensemble",
                 stream=None):
        self.total = total
        self.show = show
        self.after = after
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.start = time.perf_counter()
        self.shown = False
        self.done = 0
        self.line = StatusLine(self.stream)  # in place on a terminal, a line every few seconds in a log

    def update(self, done: int, total: int) -> int:
        self.done = done
        if self.show is False:
            return 0
        elapsed = time.perf_counter() - self.start
        if self.show is None and elapsed < self.after:
            return 0
        frac = done / total if total else 1.0
        eta = elapsed * (1 - frac) / frac if frac > 0 else float("nan")
        width = 30
        bar = "#" * int(width * frac) + "-" * (width - int(width * frac))
        self.line.write(f"{self.label} [{bar}] {done}/{total} ({100 * frac:.0f}%) {elapsed:.1f} s, eta {eta:.1f} s ")
        self.shown = True
        return 0

    def close(self, done: int | None = None) -> None:
        if self.shown:
            if done is not None:
                self.update(done, self.total)
            self.line.close()
