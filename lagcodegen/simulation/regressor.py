"""The inverse-dynamics regressor of a compiled tree model, generated, compiled and loaded on
first use (:class:`CompiledRegressor`, kept in ``CompiledModel.artifacts``): the model's own
files are not changed by it (:mod:`lagcodegen.codegen.regressor`)."""

from __future__ import annotations

import cffi
import numpy as np

from ..libraries import regressor_library
from ..errors import LagcodegenError
from ..util import c_vector

class CompiledRegressor:
    """The compiled ``<prefix>_inverse_dynamics_regressor`` and ``<prefix>_regressor_parameters``
    of the scene of ``cm`` (a :class:`~lagcodegen.simulation.ode.CompiledModel`)."""

    def __init__(self, cm):
        code = cm.code
        if f"{code.prefix}_dynamics.c" not in code.files:
            raise LagcodegenError(f"model {code.model_name!r} has no inverse-dynamics regressor (only models with a "
                                  "rigid-body tree, Model.link, have one)")
        built = regressor_library(code)  # asked of the build stage
        self.bodies, self.sources = list(built.extra), built.sources
        self.library, self.path = built.handle, built.path
        # called through cffi: a few microseconds, where ctypes' pointer arguments take tens
        self._ffi = ffi = cffi.FFI()
        self._Y = ffi.cast("int (*)(double, const double *, const double *, const double *, double *)",
                           built.address("regressor"))
        self._pi = ffi.cast("void (*)(const double *, double *)", built.address("parameters"))
        self.n, self.nv, self.ny, self.ncol = cm.n, cm.nv, cm.ny, 10 * len(self.bodies)

    def matrix(self, q, v, a, t: float, p: np.ndarray) -> np.ndarray:
        """Y (nv x 10 nb) at (q, v, a, t, p), checked."""
        n, nv = self.n, self.nv
        y = np.concatenate([c_vector(q, n, "q"), c_vector(v, nv, "v"), np.zeros(self.ny - n - nv)])
        acc = c_vector(a, nv, "a")
        p = np.ascontiguousarray(p, dtype=float)
        Y = np.empty((nv, self.ncol))
        fb = self._ffi.from_buffer
        rc = self._Y(float(t), fb("double[]", y), fb("double[]", acc), fb("double[]", p) if p.size else self._ffi.NULL,
                     fb("double[]", Y))
        if rc != 0:  # the one error it returns: its scratch array could not be allocated
            raise LagcodegenError(f"inverse-dynamics regressor: out of memory (code {rc})")
        return Y

    def parameters(self, p: np.ndarray) -> np.ndarray:
        """pi (10 nb) at the run-time parameters ``p``."""
        p = np.ascontiguousarray(p, dtype=float)
        out = np.empty(self.ncol)
        fb = self._ffi.from_buffer
        self._pi(fb("double[]", p) if p.size else self._ffi.NULL, fb("double[]", out))
        return out


def compiled_regressor(cm) -> CompiledRegressor:
    """The regressor of ``cm``, built on first use and kept with it."""
    return cm.artifacts.get(CompiledRegressor, "regressor", lambda: CompiledRegressor(cm))
