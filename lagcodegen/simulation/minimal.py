"""The face of a constrained system in minimal coordinates (:class:`MinimalSimulation`): a constrained system whose holonomic constraints were solved
symbolically (:mod:`lagcodegen.theory.minimal`) integrated as the unconstrained model of the
branch its initial state lies on, with the eliminated coordinates and the constraint residuals
reported."""

from __future__ import annotations

import time
from typing import Mapping

import numpy as np
import sympy as sp

from ..build import build
from ..codegen.constrained import generate_constrained
from ..codegen.languages import generate_code
from ..derivation import derive
from ..errors import LagcodegenError, ModelError
from ..formulation.drawing import keep_run_links
from ..formulation.scene import Scene
from ..model.events import Event, event_list
from ..model.model import Model
from ..result import Result
from ..solvers.direction import Direction
from ..solvers.request import Recording
from ..theory.constraints import ConstrainedSystem
from ..theory.minimal import reduced_contacts, reduced_model, solve_constraints
from ..solvers.base import file_initial
from ..util import check_finite, output_times, state_vector
from .constrained import ConstrainedSimulation
from .constrained_functions import _Base
from .ensemble import ensemble_minimal
from .ode import CompiledModel


class MinimalSimulation(_Base):
    """Constrained system integrated in minimal coordinates (holonomic constraints eliminated).

    The solution branch (e.g. y = -sqrt(l^2 - x^2) or +sqrt) is chosen at simulate time from q0;
    each branch is compiled once. Multipliers are not available in this formulation. Events (and
    the inequality constraints, as the terminal events ``ineq_<k>``) are located by the CVODE
    driver's root finding on the branch's model, where an eliminated coordinate (or its velocity)
    in an expression is the branch's output of that name.

    Contacts (:class:`~lagcodegen.theory.constraints.Inequality` with a restitution) are the
    branch's constraints: its model with the inequalities in the remaining coordinates
    (:meth:`contact_branch`) runs on the impact driver, so impacts jump the remaining velocities
    by Newton's law with the reduced mass matrix, resting contacts are held with their
    multipliers (``lambda_ineq_<k>``) and released where these pull, and ``res.impacts`` lists
    them (:mod:`.constrained_impacts`). A system whose only constraints are contacts runs in all
    its coordinates (nothing to eliminate).
    """

    formulation = "minimal"

    def __init__(self, system: ConstrainedSystem, outputs=None, events=(), runtime_parameters=None, values=None,
                 prefix=None, eliminate=None, verbose=False, lang: str = "c"):
        self.system = system
        self.lang = lang
        self._init_args = (system, outputs, tuple(events), runtime_parameters, values, prefix, eliminate, verbose,
                           lang)
        self.events = event_list(system, events)
        lam = {s.name for s in getattr(system, "multipliers", [])}
        for ev in self.events:
            used = sorted(s.name for s in ev.expr.free_symbols if s.name in lam)
            if used:
                raise ModelError(f"event {ev.name!r} uses the multiplier(s) {', '.join(used)}: minimal coordinates have "
                                 "no Lagrange multipliers (use formulation 'index1' or 'ggl')")
        if system.contacts and not system.holonomic and not system.nonholonomic and eliminate is None:
            self.eliminated, self.branches = [], [{}]  # contacts only: every coordinate is a minimal one
        else:
            self.eliminated, self.branches = solve_constraints(system, eliminate)
        self.remaining = [q for q in system.model.coords if q not in self.eliminated]
        outputs = ("energy", "residuals") if outputs is None else tuple(outputs)
        self._requested = outputs
        names = []
        self._python_outputs = []
        for item in outputs:
            if item in ("lambda", "constraint_forces") or item.startswith("lambda_") or item.startswith("R_"):
                raise ModelError(f"output {item!r}: minimal coordinates have no Lagrange multipliers "
                                 "(use formulation 'index1' or 'ggl')")
            if item in ("residuals", "inequalities") or item.startswith("g_") or item.startswith("gdot_"):
                self._python_outputs.append(item)
            else:
                names.append(item)
        self._model_outputs = names
        self._runtime_parameters = runtime_parameters
        self._values = dict(values or {})
        self._prefix = prefix
        self._verbose = verbose
        self._compiled: dict[int, CompiledModel] = {}
        self._contact_sims: dict = {}  # branch -> the ConstrainedSimulation of its contacts (systems with contacts)
        self._reduced: dict[int, Model] = {}
        model = system.model
        folded_names = [s.name for s in model.params]
        if runtime_parameters is not None:
            folded_names = [nm for nm in folded_names if nm not in set(runtime_parameters)]
        else:
            folded_names = []
        defaults = {s.name: v for s, v in model.params.items()}
        self._folded = {nm: float(self._values.get(nm, defaults[nm])) for nm in folded_names}
        # numerical constraint residuals for the outputs g_j, gdot_j (from the reconstructed full state)
        args = list(model.coords) + list(model.speeds) + [model.t] + list(model.params)
        self._args = args
        self._g_fn = sp.lambdify(args, list(system.holonomic), modules="numpy")
        self._s_fn = sp.lambdify(args, list(system.velocity_residuals()), modules="numpy")

    @property
    def state_names(self) -> list[str]:
        return [q.name for q in self.remaining] + [f"{q.name}_dot" for q in self.remaining]

    @property
    def param_names(self) -> list[str]:
        names = [s.name for s in self.system.model.params]
        return names if self._runtime_parameters is None else list(self._runtime_parameters)

    def reduced_branch(self, b: int) -> Model:
        """The model of branch ``b`` in the remaining coordinates (:func:`reduced_model`), made once."""
        if b not in self._reduced:
            self._reduced[b] = reduced_model(self.system, self.branches[b], name=f"{self.system.model.name}_min{b}")
        return self._reduced[b]

    def compiled_branch(self, b: int) -> CompiledModel:
        if b not in self._compiled:
            red = self.reduced_branch(b)
            scene = Scene(derive(red), outputs=[*self._model_outputs, *[f"{q.name}" for q in self.eliminated],
                                                 *[f"{q.name}_dot" for q in self.eliminated]],
                          runtime_parameters=self._runtime_parameters, values=self._values,
                          prefix=self._prefix and f"{self._prefix}_b{b}")
            self._compiled[b] = CompiledModel.from_built(build(generate_code(scene, self.lang), native=True,
                                                                      verbose=self._verbose))
        return self._compiled[b]

    def contact_branch(self, b: int):
        """The contacts of branch ``b`` (:func:`lagcodegen.theory.minimal.reduced_contacts`: the
        system's inequalities in the remaining coordinates) compiled as a constrained system of
        the branch's model without equality constraints, index-1 form: free flight is the
        branch's ODE, impacts jump its velocities by Newton's law with its mass matrix (sec. 4.3),
        resting contacts are held with their multipliers and released where these pull
        (:mod:`.constrained_impacts`)."""
        sim = self._contact_sims.get(b)
        if sim is None:
            red = self.reduced_branch(b)
            system = reduced_contacts(self.system, self.branches[b], red)
            outs = [*self._model_outputs, *[q.name for q in self.eliminated],
                    *[f"{q.name}_dot" for q in self.eliminated]]
            events = [Event(ev.name, self._on_branch(ev.expr, b), ev.direction, ev.terminal) for ev in self.events
                      if not (ev.name.startswith("ineq_") and ev.name[5:].isdigit())]
            code, info = generate_constrained(system, outputs=outs, events=events,
                                              runtime_parameters=self._runtime_parameters, values=self._values,
                                              prefix=self._prefix and f"{self._prefix}_c{b}", lang=self.lang)
            cm = CompiledModel.from_built(build(code, native=True, verbose=self._verbose))
            sim = self._contact_sims[b] = ConstrainedSimulation(system, "index1", cm, info, "auto", False)
        return sim

    def _on_branch(self, expr, b: int):
        """``expr`` (of the full model's coordinates and velocities) on branch ``b``: the eliminated
        coordinates and their velocities substituted."""
        model = self.system.model
        sol = self.branches[b]
        sub = dict(sol)
        for qe, e in sol.items():
            sub[model.dot(qe)] = sp.diff(e, model.t) + sum((sp.diff(e, q) * model.dot(q) for q in self.remaining),
                                                           sp.Integer(0))
        return sp.sympify(expr).xreplace(sub)

    def _branch_for(self, q: np.ndarray, t0: float, vals: dict, tol: float) -> int:
        model = self.system.model
        if not self.eliminated:
            return 0
        subs = {**{s: q[i] for i, s in enumerate(model.coords)}, model.t: t0,
                **{s: vals[s.name] for s in model.params}}
        best, err = None, np.inf
        for b, sol in enumerate(self.branches):
            try:
                e = max(abs(complex(sp.sympify(sol[qe]).xreplace(subs).evalf()) - q[model.index(qe)])
                        for qe in self.eliminated)
            except (TypeError, ValueError):
                continue
            if e < err:
                best, err = b, e
        if best is None or err > tol * (1 + float(np.max(np.abs(q)))):
            raise ModelError(f"minimal coordinates: no solution branch of the constraints matches q0 "
                             f"(closest differs by {err:.3g}); inconsistent initial conditions")
        return best

    def simulate(self, t, q0=None, v0=None, *, params: Mapping | None = None, solver=None, rtol: float = 1e-8,
                 atol=1e-10, events: bool | None = None, initial: str = "check", ic_tol: float = 1e-8,
                 raise_on_error: bool = True, **options) -> Result:
        """Integrate in the remaining coordinates; q0/v0 are given for all n coordinates.

        ``initial="check"`` requires them to satisfy the constraints (within ``ic_tol``);
        ``"project"`` keeps the remaining coordinates and velocities and recomputes the
        eliminated ones. ``solver`` and ``options`` are those of the ODE of a compiled scene
        (:meth:`CompiledModel.simulate <lagcodegen.simulation.ode.CompiledModel.simulate>`);
        ``events`` None or True locates the compiled events (the ``events`` of the constructor and
        the inequality constraints), False none; minimal coordinates have no Baumgarte
        stabilization or projection (they have no drift to correct): such options raise.

        ``sensitivities`` (CVODE): forward sensitivities of the branch's ODE (states: the remaining
        coordinates; the eliminated ones are outputs and have theirs) with respect to run-time
        parameters and the remaining coordinates' initial values (``"<q>(0)"``, ``"<q>_dot(0)"``;
        the eliminated coordinates follow them, as with ``initial="project"``).
        """
        roots = self.check_events(events)
        t = output_times(t)
        model = self.system.model
        self._check_directions(options.get("sensitivities", getattr(solver, "sensitivities", None)))
        q, v, vals = self._start(q0, v0, params, float(t[0]), initial, ic_tol)
        tol = ic_tol if initial == "check" else np.inf
        b = self._branch_for(q, float(t[0]), vals, tol)
        cm = self.contact_branch(b) if self.system.contacts else self.compiled_branch(b)
        idx = [model.index(qr) for qr in self.remaining]
        run_params = {k: vals[k] for k in cm.param_names}
        start = time.perf_counter()
        if self.system.contacts:  # the contacts on the branch's model, on the impact driver
            res = cm.simulate(t, q0=q[idx], v0=v[idx], params=run_params, solver=solver,
                                                  rtol=rtol, atol=atol, events=roots, raise_on_error=raise_on_error,
                                                  **options)
        else:
            res = cm.simulate(t, q0=q[idx], v0=v[idx], params=run_params, solver=solver, rtol=rtol, atol=atol,
                              raise_on_error=raise_on_error, events=self.events if roots else (), **options)
        res.stats["wall_time"] = time.perf_counter() - start
        res.stats["branch"] = b
        self._add_residuals(res, vals)
        res.formulation = "minimal"
        res.model_name = model.name  # titles name the system, not its reduced model
        keep_run_links(res)  # the rods that the reduced model's geometry hides (square roots)
        if res.events is None:
            res.events = []
        return res

    def integrator(self, *, q0=None, v0=None, t0: float = 0.0, params: Mapping | None = None, solver=None,
                   rtol: float = 1e-8, atol=1e-10, initial: str = "check", ic_tol: float = 1e-8, **options):
        """An integrator object (:meth:`CompiledModel.integrator
        <lagcodegen.simulation.ode.CompiledModel.integrator>`) on the branch ``q0`` lies on: q0/v0
        for all n coordinates, checked as :meth:`simulate` does (``initial``, ``ic_tol``); its
        state and parameters are those of the branch's model (the remaining coordinates,
        :attr:`state_names`)."""
        if self.system.contacts:
            raise LagcodegenError("the integrator object does not run systems with contacts (impacts with "
                                  "restitution), in minimal coordinates either: use simulate(), whose impact "
                                  "driver applies the jumps")
        model = self.system.model
        t0 = check_finite(t0, "t0")
        q, v, vals = self._start(q0, v0, params, t0, initial, ic_tol)
        cm = self.compiled_branch(self._branch_for(q, t0, vals, ic_tol if initial == "check" else np.inf))
        idx = [model.index(qr) for qr in self.remaining]
        return cm.integrator(q0=q[idx], v0=v[idx], t0=t0, params={k: vals[k] for k in cm.param_names},
                             solver=solver, rtol=rtol, atol=atol, **options)

    def ensemble(self, t, q0=None, v0=None, *, params=None, threads=None, save="final", executor=None,
                 progress=None, chunk_size=None, initial: str = "check", ic_tol: float = 1e-8, **options):
        """N runs in one call per solution branch into the generated C (see
        :meth:`lagcodegen.simulation.ode.CompiledModel.ensemble`); q0/v0 (N, n) for all n
        coordinates, checked as :meth:`simulate` does (``initial``, ``ic_tol``)."""
        if self.system.contacts:
            raise LagcodegenError("ensembles of systems with contacts are not supported in minimal coordinates: "
                                  "run the members with simulate (each a call of the impact driver)")
        return ensemble_minimal(self, t, q0, v0, params=params,
                                recording=Recording(save=save, threads=threads, progress=progress),
                                executor=executor, chunk_size=chunk_size, initial=initial, ic_tol=ic_tol,
                                options=options)

    def _start(self, q0, v0, params, t0: float, initial: str, ic_tol: float):
        """(q, v, parameter values by name) of a run or integrator from ``t0``: q0/v0 for all n
        coordinates, run-time parameters checked, the initial state checked against the
        constraints when ``initial`` is "check" ("project" and "none" leave it to the branch)."""
        model = self.system.model
        names = [q.name for q in model.coords]
        q0, v0 = file_initial(self, q0, v0)
        q = state_vector(q0, names, "q0")
        v = state_vector(v0, names, "v0")
        vals = {**{s.name: v_ for s, v_ in model.params.items()}, **self._values}
        for k, val in (params or {}).items():
            if k not in self.param_names:
                raise LagcodegenError(f"{k!r} is not a run-time parameter (run-time parameters: "
                                      f"{', '.join(self.param_names) or 'none'})")
            vals[k] = check_finite(val, f"parameter {k!r}")
        if initial == "check":
            self.system.check_initial(q, v, vals, t0=t0, tol=ic_tol)
        elif initial not in ("project", "none"):
            raise LagcodegenError(f"initial must be 'check', 'project' or 'none', got {initial!r}")
        return q, v, vals

    def _check_directions(self, names) -> None:
        """Sensitivity directions that name an eliminated coordinate's initial value raise: it is
        a function of the remaining coordinates (the branch's outputs of that name have
        sensitivities with respect to theirs)."""
        if names is None:
            return
        for name in [names] if isinstance(names, str) else names:
            initial = Direction.initial(name) if isinstance(name, str) else None
            if initial is not None:
                base = initial[1]
                if any(q.name == base for q in self.eliminated):
                    raise LagcodegenError(f"sensitivities: {name!r}: {base} is eliminated in minimal coordinates (a "
                                          f"function of {', '.join(q.name for q in self.remaining)}); give the "
                                          "initial values of the remaining coordinates")

    def check_events(self, events) -> bool:
        """Whether a run locates the compiled events (``events`` of simulate or ensemble: None or
        True, the compiled ones; False, none); anything else raises."""
        if events is None or events is True:
            return bool(self.events)
        if events is False:
            return False
        raise LagcodegenError(f"events={events!r:.60}: the events of a constrained system are compiled in "
                              "(compile_constrained(events=...)); events= of a run is True or False")

    def __reduce__(self):
        """Pickled by its constructor's arguments (the branches are compiled again, from the cache)."""
        return MinimalSimulation, self._init_args

    def full_state(self, res: Result) -> tuple[np.ndarray, np.ndarray]:
        """(q, q') of all n coordinates along a result (eliminated ones from the outputs)."""
        model = self.system.model
        q = np.column_stack([res[c.name] for c in model.coords])
        v = np.column_stack([res[f"{c.name}_dot"] for c in model.coords])
        return q, v

    def _add_residuals(self, res: Result, vals: dict) -> None:
        want = self._python_outputs
        if not want:
            return
        model = self.system.model
        q, v = self.full_state(res)
        args = [q[:, i] for i in range(model.n)] + [v[:, i] for i in range(model.n)] + [res.t]
        args += [np.full_like(res.t, vals[s.name]) for s in model.params]
        JH, J = self.system.n_holonomic, self.system.J
        g = np.atleast_2d(np.array([np.broadcast_to(x, res.t.shape) for x in self._g_fn(*args)], dtype=float))
        s = np.atleast_2d(np.array([np.broadcast_to(x, res.t.shape) for x in self._s_fn(*args)], dtype=float))
        extra = {}
        for j in range(JH):
            extra[f"g_{j}"] = g[j]
        for j in range(J):
            extra[f"gdot_{j}"] = s[j]
        for item in want:
            if item == "residuals":
                res.outputs.update(extra)
            elif item in extra:
                res.outputs[item] = extra[item]


