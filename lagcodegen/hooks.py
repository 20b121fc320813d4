"""Entry points by which a lower stage offers what a higher stage implements.

The symbolic objects of the theory and the model files (a Routhian reduction, a model file)
offer ``.compile()`` for convenience, but compiling is the business of stages further down
the pipeline (formulation, codegen, build, solvers). Those stages register their
implementation here when :mod:`lagcodegen` is imported (:mod:`lagcodegen.api`), so that
imports keep running one way: nothing below the API imports the API.
"""

from __future__ import annotations

from typing import Any, Callable

from .errors import LagcodegenError

_IMPLEMENTATIONS: dict[str, Callable[..., Any]] = {}


def register(name: str, implementation: Callable[..., Any]) -> None:
    """Make ``implementation`` the one :func:`call` runs for ``name``."""
    _IMPLEMENTATIONS[name] = implementation


def call(name: str, *args: Any, **kwargs: Any) -> Any:
    """Run the implementation registered for ``name``."""
    try:
        implementation = _IMPLEMENTATIONS[name]
    except KeyError:
        raise LagcodegenError(f"{name!r} is implemented by lagcodegen.api: import lagcodegen first") from None
    return implementation(*args, **kwargs)
