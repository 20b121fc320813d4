"""The compiled simulations Python holds (the faces): one protocol, :class:`Simulation`, three faces.

* :class:`~.ode.CompiledModel`: the ODE of a compiled scene (plain, Routhian-reduced);
* :class:`~.constrained.ConstrainedSimulation`: a constrained system in the index-1 (CVODE) or
  GGL (IDA) form, its compiled functions in :mod:`.constrained_functions`;
* :class:`~.minimal.MinimalSimulation`: a constrained system in minimal coordinates, run as the
  ODE of the solution branch its initial state lies on;

plus their ensembles (:mod:`.ensemble`) and switched runs of two faces (:mod:`.hybrid`). A face
checks the run's inputs (times, initial state, parameters) and leaves the integration to a
solver family (:mod:`lagcodegen.solvers`), resolved from ``solver=`` and the option keywords by
:func:`lagcodegen.solvers.registry.resolve`, the same for ``simulate`` and ``ensemble``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class Simulation(Protocol):
    """What every face offers: its names, a run, an ensemble of runs, and pickling (by its
    generated sources, rebuilt from the receiving process's cache)."""

    @property
    def state_names(self) -> list[str]: ...

    @property
    def param_names(self) -> list[str]: ...

    def simulate(self, t, q0=None, v0=None, **options): ...

    def ensemble(self, t, q0=None, v0=None, **options): ...

    def __reduce__(self): ...


__all__ = ["Simulation"]
