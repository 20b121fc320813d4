"""Sensitivity directions as values, parsed once: a run-time parameter (``"g"``), the initial
value of a coordinate (``"theta(0)"``) or of its velocity (``"theta_dot(0)"``).

:meth:`Direction.parse` is the one place such a name is read; the sensitivity drivers, the fits
(Python and command line) and the minimal-coordinate simulations take :class:`Direction` values
from it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Sequence

from ..errors import LagcodegenError

#: What a direction names: a run-time parameter, a coordinate's initial value, a velocity's, or
#: another state's (a quadrature state, e.g. an ignorable coordinate of a Routhian reduction).
Kind = Literal["parameter", "position", "velocity", "state"]

_INITIAL = "(0)"
_VELOCITY = "_dot"
#: How the initial values are written, for messages.
SPELLING = "'<coordinate>(0)', '<coordinate>_dot(0)'"
_WRITE = "write '<coordinate>(0)' or '<coordinate>_dot(0)'"


@dataclass(frozen=True)
class Direction:
    """One sensitivity direction: ``name`` as written, its ``kind`` and its ``target`` (the
    parameter's or the coordinate's name)."""

    name: str
    kind: Kind
    target: str

    @staticmethod
    def initial(name: str) -> tuple[Kind, str] | None:
        """("position" | "velocity", coordinate) of a name written as an initial value
        (``q(0)``, ``q_dot(0)``), by its spelling alone; else None."""
        if not name.endswith(_INITIAL) or len(name) <= len(_INITIAL):
            return None
        base = name[:-len(_INITIAL)]
        if base.endswith(_VELOCITY) and len(base) > len(_VELOCITY):
            return "velocity", base[:-len(_VELOCITY)]
        return "position", base

    @classmethod
    def parse(cls, name, *, params: Sequence[str], coords: Sequence[str], states: Sequence[str] = (),
              what: str = "sensitivities") -> "Direction":
        """The direction ``name`` among the run-time parameters ``params`` and the initial values
        of the coordinates ``coords``, their velocities and the other ``states`` (quadratures);
        LagcodegenError naming it (``what``: the message's prefix) when it is none of them. A
        velocity's initial value is read as such when its coordinate exists (``x_dot(0)`` of a
        coordinate ``x``)."""
        if not isinstance(name, str):
            raise LagcodegenError(f"{what}: {name!r:.80} is not a name")
        if name in params:
            return cls(name, "parameter", name)
        initial = cls.initial(name)
        if initial is not None:
            kind, target = initial
            if kind == "velocity" and target in coords:
                return cls(name, "velocity", target)
            base = name[:-len(_INITIAL)]
            if base in coords:
                return cls(name, "position", base)
            if base in states:
                return cls(name, "state", base)
            raise LagcodegenError(f"{what}: {name!r:.80} names no initial value (coordinates: {', '.join(coords)}; "
                                  f"{_WRITE})")
        raise LagcodegenError(f"{what}: {name!r:.80} is neither a run-time parameter ({', '.join(params) or 'none'}) "
                              f"nor an initial value ({SPELLING})")

    def state_index(self, coords: Sequence[str], states: Sequence[str] = ()) -> int:
        """The index of an initial value in the state (q, q', the other ``states`` after them as
        in ``states``, which then lists every state): a coordinate's, n + its velocity's;
        ValueError for a parameter."""
        if self.kind == "parameter":
            raise ValueError(f"{self.name!r} is a parameter, not an initial value")
        if self.kind == "state":
            return list(states).index(self.target)
        i = list(coords).index(self.target)
        return i if self.kind == "position" else len(coords) + i


def parse_all(names, *, params: Sequence[str], coords: Sequence[str], states: Sequence[str] = (),
              folded=(), listed_in: str = "", what: str = "sensitivities") -> list[Direction]:
    """:meth:`Direction.parse` of each of ``names`` (one name or a sequence), at least one, none
    repeated; a name in ``folded`` (a parameter folded into the code as a constant) is refused,
    to be listed in ``listed_in``."""
    if isinstance(names, str):
        names = [names]
    names = list(names)
    if not names:
        raise LagcodegenError(f"{what}: give at least one parameter or initial value")
    out: list[Direction] = []
    for j, name in enumerate(names):
        if isinstance(name, str) and names.index(name) != j:
            raise LagcodegenError(f"{what}: {name!r:.80} is given twice")
        if isinstance(name, str) and name in folded and name not in params and Direction.initial(name) is None:
            raise LagcodegenError(f"{what}: parameter {name!r:.80} is folded into the code as a constant; list it "
                                  f"in {listed_in}")
        out.append(Direction.parse(name, params=params, coords=coords, states=states, what=what))
    return out
