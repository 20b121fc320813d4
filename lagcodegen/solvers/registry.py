"""The registry of solver families (one line per family) and the one resolution of a run's
solver options into a family object, which ``simulate`` and ``ensemble`` of every face share
(:func:`resolve`), so that the two cannot drift apart.

* ``solver=CVODE(...)``, ``IDA(...)``, ``Taylor(...)``: that object (keywords given beside it
  must not contradict it);
* else the keyword spellings: ``method`` chooses the family among those that run the face
  (``"adams"``/``"bdf"``: CVODE, ``"taylor"``: Taylor, GGL: IDA, ``"auto"``: Taylor or Adams by
  :func:`lagcodegen.solvers.auto.choose_method`, the model's size and measured costs) and the
  other keywords become its fields;
* a keyword the family does not have raises LagcodegenError naming it, unless it asks for
  nothing (``backend="native"``, ``linear_solver="dense"``, ... :data:`.family.NEUTRAL`).
"""

from __future__ import annotations

from ..errors import LagcodegenError
from .auto import AUTO_TAYLOR_MAX_N, AUTO_TAYLOR_TIGHT_MAX_N, choose_method
from .cvode import CVODE
from .family import FACES, Family
from .ida import IDA
from .taylor import Taylor

#: Every solver family, by name. The first family that runs a face is that face's default; a
#: new family is a folder under solvers/ (options object, runner, ensemble runner) plus one line here.
FAMILIES: dict[str, type[Family]] = {
    "cvode": CVODE,
    "ida": IDA,
    "taylor": Taylor,
}


def methods(face: str) -> list[str]:
    """The ``method=`` spellings of the families that run ``face``."""
    return [m for cls in FAMILIES.values() if face in cls.faces for m in cls.methods]


def family_class(face: str, method: str | None) -> type[Family]:
    """The family that runs ``face`` with ``method`` (None: the face's default)."""
    for cls in FAMILIES.values():
        if face in cls.faces and (method is None or method in cls.methods):
            return cls
    if face == "ggl":
        raise LagcodegenError(f"IDA integrates with BDF only (method='bdf'), not method={method!r}: a system "
                              "compiled with formulation='ggl' runs on IDA; compile_constrained(system, 'index1') "
                              "runs it on CVODE's methods and on Taylor")
    spellings = methods(face) + (["auto"] if face == "ode" else [])
    raise LagcodegenError(f"method must be one of {', '.join(spellings)}, got {method!r}")


_CACHE: dict = {}


def _kind(value):
    """The type of an option's value (of each item of a tuple) in the key of :data:`_CACHE`: values
    equal across types (2 and 2.0, 1 and True) resolve differently (``order=2.0`` is refused)."""
    kind = type(value)
    return tuple(map(_kind, value)) if kind is tuple else kind


def resolve(face: str, solver, options: dict, n: float = 0, rtol: float = 1e-8, *, runs: str = "run",
            costs=None) -> Family:
    """The family object of a run on ``face`` ("ode", "index1", "ggl"): ``solver`` (a family
    object or None) with ``options`` (the run's other keywords: method, linear_solver, ...)
    applied, checked against the face and against the kind of run asked for (``runs``: "run",
    "stepper", "ensemble", "prepared"; the family's ``runs`` table). ``n``, ``rtol`` and ``costs`` (rtol ->
    the model's measured :class:`~lagcodegen.solvers.auto.MethodCosts` or None) choose the
    family of ``method="auto"`` (:func:`~lagcodegen.solvers.auto.choose_method`)."""
    if solver is None and face == "ode" and options.get("method") == "auto":
        options = {**options, "method": choose_method(n, rtol, costs)}
    try:
        key = (face, runs, solver, tuple(options.items()), tuple(map(_kind, options.values())), n, rtol)
        hit = _CACHE.get(key)
    except TypeError:  # unhashable values (arrays): resolved every time
        key = hit = None
    if hit is not None:
        return hit
    if solver is None:
        options = dict(options)
        method = options.pop("method", None)
        cls = family_class(face, method)
        if "method" in cls.fields() and method is not None:
            options["method"] = method
        family = cls.from_options(face, options)
    elif isinstance(solver, Family):
        options = dict(options)
        method = options.pop("method", None)
        if method is not None and method not in type(solver).methods + ("auto",):
            raise LagcodegenError(f"method={method!r} contradicts solver={solver!r}")
        if method is not None and "method" in type(solver).fields() and method != "auto":
            options["method"] = method
        family = solver.updated(face, options)
    else:
        raise LagcodegenError(f"solver must be {', '.join(f'{c.__name__}(...)' for c in FAMILIES.values())}, "
                              f"got {solver!r}")
    family.check_face(face)
    family.check_runs(face, runs)
    if key is not None:
        if len(_CACHE) >= 256:
            _CACHE.clear()
        _CACHE[key] = family
    return family


__all__ = ["AUTO_TAYLOR_MAX_N", "AUTO_TAYLOR_TIGHT_MAX_N", "CVODE", "FACES", "FAMILIES", "IDA", "Taylor",
           "choose_method", "family_class", "methods", "resolve"]
