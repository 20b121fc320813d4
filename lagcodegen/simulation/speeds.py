"""The face of a constrained system with nonholonomic constraints in minimal form
(:class:`IndependentSpeedsSimulation`): the ODE in independent speeds (q, u)
(:mod:`lagcodegen.theory.speeds`), its independent speeds chosen where a run starts (column-pivoted
QR of A at q0, unless given), each choice compiled once."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..build import build
from ..codegen.languages import generate_code
from ..derivation import derive
from ..errors import ModelError
from ..formulation.scene import Scene
from ..result import Result
from ..theory.constraints import ConstrainedSystem
from ..theory.speeds import choose_independent, independent_speeds_model, pivoted_solve
from ..util import state_values
from .ode import CompiledModel


class IndependentSpeedsSimulation:
    """A system with nonholonomic constraints integrated in independent speeds (Maggi's,
    Voronets' and Kane's form). :meth:`simulate` takes the initial coordinates and all their
    rates (``v0``: n values satisfying the constraints A q' + A0 = 0, checked); its result's
    state is (q, u), u the rates of the independent coordinates, with the holonomic residuals
    ``g_<j>`` and the requested outputs.

    The independent speeds: ``independent`` (coordinate names), or chosen at each run's initial
    state by column-pivoted QR of A (the best-conditioned choice there); a choice is singular
    where A_dep is (e.g. a knife edge's y' = x' tan(theta) at theta = pi/2): a run that reaches
    such a state stops with a non-finite value.
    """

    formulation = "minimal"

    def __init__(self, system: ConstrainedSystem, *, independent: Sequence[str] | None = None, outputs=None,
                 runtime_parameters=None, values: Mapping | None = None, prefix: str | None = None,
                 verbose: bool = False, lang: str = "c"):
        if system.inequalities:
            raise ModelError("independent speeds: inequality constraints are not taken (use formulation 'index1', "
                             "whose impact driver does)")
        self.system = system
        self._independent = None if independent is None else choose_independent(system, independent)[0]
        self._outputs = ["energy"] if outputs is None else list(outputs)
        self._scene_options = dict(runtime_parameters=runtime_parameters, values=dict(values or {}), prefix=prefix)
        self._verbose, self.lang = verbose, lang
        self._compiled: dict[tuple, CompiledModel] = {}
        model = system.model
        self._A = sp.lambdify(list(model.coords) + [model.t] + list(model.params), system.A, modules="numpy")
        self._A0 = sp.lambdify(list(model.coords) + [model.t] + list(model.params), system.A0, modules="numpy")

    def choose(self, q0, t0: float = 0.0, params: Mapping | None = None) -> list[int]:
        """The independent coordinates (indices) at ``q0``: the given ones, or by column-pivoted QR
        of A(q0, t0) (its pivot columns are the dependent rates)."""
        if self._independent is not None:
            return list(self._independent)
        return choose_independent(self.system, A=self._matrix(self._A, q0, t0, params))[0]

    def _parameter_values(self, params: Mapping | None) -> dict:
        """The parameters' values by symbol: defaults, the compiled values, then ``params``."""
        model = self.system.model
        vals = {s.name: v for s, v in model.params.items()}
        vals.update(self._scene_options["values"])
        vals.update(params or {})
        return {s: float(vals[s.name]) for s in model.params}

    def _matrix(self, f, q0, t0, params):
        vals = self._parameter_values(params)
        args = list(q0) + [t0] + [vals[s] for s in self.system.model.params]
        return np.atleast_2d(np.array(f(*args), dtype=float))

    def compiled(self, independent: Sequence[int], q0=None, t0: float = 0.0,
                 params: Mapping | None = None) -> CompiledModel:
        """The compiled model of one choice of independent speeds (built once), its dependent
        rates solved with the pivots largest at ``q0`` (default: the neutral configuration)."""
        model = self.system.model
        q0 = model.neutral() if q0 is None else list(q0)
        at = {**{q: float(x) for q, x in zip(model.coords, q0)}, model.t: float(t0),
              **{s: float(v) for s, v in self._parameter_values(params).items()}}
        dep = [i for i in range(model.n) if i not in independent]
        A = self.system.A
        _, pivots = pivoted_solve(A[:, dep], sp.zeros(A.shape[0], 1), at) if dep else (None, ())
        key = (tuple(independent), pivots)
        if key not in self._compiled:
            names = [model.coords[i].name for i in independent]
            suffix = "_".join(str(i) for i in independent) + ("_p" + "".join(map(str, pivots)) if pivots else "")
            reduced = independent_speeds_model(self.system, independent=names, at=at,
                                               name=f"{model.name}_u{suffix}")
            extra = [f"g_{j}" for j in range(self.system.n_holonomic)]
            opts = dict(self._scene_options)
            if opts["prefix"]:
                opts["prefix"] = f"{opts['prefix']}_u{suffix}"
            scene = Scene(derive(reduced), jacobian=False,
                          outputs=self._outputs + [o for o in extra if o not in self._outputs], **opts)
            self._compiled[key] = CompiledModel.from_built(build(generate_code(scene, self.lang), native=True,
                                                                 verbose=self._verbose))
        return self._compiled[key]

    def simulate(self, t, q0, v0=None, *, params: Mapping | None = None, **options) -> Result:
        """A run from the coordinates ``q0`` and their rates ``v0`` (n values or names -> values,
        satisfying A q' + A0 = 0 to 1e-8 relative); ``options`` those of
        :meth:`CompiledModel.simulate` (solver, rtol, atol, events, ...)."""
        model = self.system.model
        names = [q.name for q in model.coords]
        q = np.array(state_values(q0, names, "q0"), dtype=float)
        v = np.array(state_values(v0, [s.name for s in model.speeds], "v0"), dtype=float)
        t0 = float(np.asarray(t, dtype=float).ravel()[0])
        A, A0 = self._matrix(self._A, q, t0, params), self._matrix(self._A0, q, t0, params).ravel()
        residual = A @ v + A0
        scale = max(1.0, float(np.abs(A).max() * np.abs(v).max()))
        if np.abs(residual).max() > 1e-8 * scale:
            worst = int(np.argmax(np.abs(residual)))
            raise ModelError(f"v0 does not satisfy the velocity constraints: row {worst} of A q' + A0 is "
                             f"{residual[worst]:.3g} (give rates on the constraint manifold)")
        ind = self.choose(q, t0, params)
        cm = self.compiled(ind, q, t0, params)
        return cm.simulate(t, q0=q, v0=v[ind], params=params, **options)
