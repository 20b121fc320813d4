"""The canonical form of a model: one text, the same in every process, that changes with any
change of what the model states (the pipeline cache's key: :func:`lagcodegen.compile_model`).

One job: :func:`canonical_form` walks a :class:`~lagcodegen.model.Model` (or any value made of
the model's own parts) field by field in declaration order and writes each leaf exactly: sympy
expressions and matrices as ``sympy.srepr`` (symbols with their assumptions, Floats with their
precision), Python numbers by ``repr`` (exact for floats), strings, lists, tuples and dicts in
their order, numpy arrays by dtype, shape and bytes. A link of a tree names its parent and
children (the tree is not walked twice); caches (a link's pose) are left out.

Anything it cannot write exactly returns None, and the caller then does not cache (never a wrong
hit): an object of a class outside the model's own (a subclass too), a sympy function defined in
Python (a ``Function`` subclass of the user's or one with an implementation attached,
``implemented_function``), a value shared in a cycle. ``extra`` adds the fields of classes of a
higher stage (a constrained system) by a function returning them as (name, value) pairs.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Mapping

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef

from .bodies import Joint, Link, Placement
from .events import Event
from .model import Model, Particle, PlanarBody, Point, RigidBody
from .speeds import GivenEquations

#: The model's own classes, walked by their dataclass fields; per class the fields left out
#: (caches, and the links of a tree that are written by name).
FIELDS_LEFT_OUT: dict[type, tuple[str, ...]] = {
    Model: (), Point: (), Particle: (), PlanarBody: (), RigidBody: (), Joint: (), Placement: (),
    GivenEquations: (), Event: (), Link: ("_pose",)}


class _Unsupported(Exception):
    """A value the canonical form cannot write exactly."""


def _sympy_type_ok(cls: type) -> bool:
    """sympy's own node classes, and undefined functions without an implementation attached."""
    if issubclass(cls, AppliedUndef):
        return getattr(cls, "_imp_", None) is None
    return (cls.__module__ or "").startswith("sympy.")


class _Writer:
    def __init__(self, extra: Mapping[type, Callable[[Any], list]]):
        self.extra = dict(extra)
        self.parts: list[str] = []
        self.active: set[int] = set()
        self.types_ok: dict[type, bool] = {}

    def expr(self, value) -> None:
        nodes = value if isinstance(value, sp.MatrixBase) else [value]
        for node in nodes:
            for sub in sp.preorder_traversal(node):
                cls = type(sub)
                ok = self.types_ok.get(cls)
                if ok is None:
                    ok = self.types_ok[cls] = _sympy_type_ok(cls)
                if not ok:
                    raise _Unsupported(f"the sympy class {cls.__name__} (defined in {cls.__module__})")
        self.parts.append(sp.srepr(value))

    def write(self, value) -> None:  # noqa: C901 - one branch per kind of leaf
        out = self.parts.append
        if value is None or isinstance(value, (bool, str)):
            out(repr(value))
        elif type(value) in (int, float, np.float64):
            out(f"{type(value).__name__}:{value!r}")
        elif isinstance(value, (sp.Basic, sp.MatrixBase)):
            self.expr(value)
        elif isinstance(value, np.ndarray):
            if value.dtype.hasobject:
                self.sequence("ndarray", value.tolist())
            else:
                out(f"ndarray:{value.dtype.str}:{value.shape}:{value.tobytes().hex()}")
        elif type(value) in (list, tuple):
            self.sequence(type(value).__name__, value)
        elif type(value) is dict:
            with self.inside(value):
                out(f"dict:{len(value)}[")
                for k, v in value.items():
                    self.write(k)
                    out(":")
                    self.write(v)
                    out(",")
                out("]")
        elif type(value) in FIELDS_LEFT_OUT:
            self.fields(value)
        elif type(value) in self.extra:
            with self.inside(value):
                self.named(type(value).__name__, self.extra[type(value)](value))
        else:
            raise _Unsupported(f"a {type(value).__module__}.{type(value).__qualname__}")

    def sequence(self, tag: str, items) -> None:
        with self.inside(items):
            self.parts.append(f"{tag}:{len(items)}[")
            for item in items:
                self.write(item)
                self.parts.append(",")
            self.parts.append("]")

    def fields(self, obj) -> None:
        left_out = FIELDS_LEFT_OUT[type(obj)]
        pairs = []
        for f in dataclasses.fields(obj):
            if f.name in left_out:
                continue
            value = getattr(obj, f.name)
            if isinstance(obj, Link) and f.name == "parent":
                value = None if value is None else ("link", value.name)
            elif isinstance(obj, Link) and f.name == "children":
                value = [("link", child.name) for child in value]
            pairs.append((f.name, value))
        with self.inside(obj):
            self.named(type(obj).__name__, pairs)

    def named(self, tag: str, pairs: list) -> None:
        self.parts.append(f"{tag}(")
        for name, value in pairs:
            self.parts.append(f"{name}=")
            self.write(value)
            self.parts.append(";")
        self.parts.append(")")

    def inside(self, obj):
        writer = self

        class _Guard:
            def __enter__(self):
                if id(obj) in writer.active:
                    raise _Unsupported("a value that contains itself")
                writer.active.add(id(obj))

            def __exit__(self, *exc):
                writer.active.discard(id(obj))

        return _Guard()


def canonical_form(value, extra: Mapping[type, Callable[[Any], list]] | None = None) -> str | None:
    """The canonical text of ``value`` (a Model, its parts, options made of numbers, strings,
    lists, dicts and sympy objects), or None if some part of it cannot be written exactly (see
    the module's docstring): then nothing may be cached by it."""
    writer = _Writer(extra or {})
    try:
        writer.write(value)
    except (_Unsupported, RecursionError):
        return None
    return "".join(writer.parts)


def why_not_canonical(value, extra: Mapping[type, Callable[[Any], list]] | None = None) -> str | None:
    """What part of ``value`` has no canonical form (None if it has one): for messages."""
    writer = _Writer(extra or {})
    try:
        writer.write(value)
    except _Unsupported as exc:
        return str(exc)
    except RecursionError:
        return "a value nested too deeply"
    return None
