"""Run-time inertial parameters of URDF links (:func:`lagcodegen.modelfile.urdf.load`'s
``inertial_parameters``): each named link's dynamic parameters, Pinocchio's
``Inertia.toDynamicParameters`` (:data:`lagcodegen.model.bodies.DYNAMIC_PARAMETERS`)

    <link>_m, <link>_mx, <link>_my, <link>_mz, <link>_Ixx, <link>_Ixy, <link>_Iyy, <link>_Ixz,
    <link>_Iyz, <link>_Izz

(the mass, the first moments m c, the inertia about the link frame's origin, in the link's axes;
``<link>`` the link's name made an identifier), defaults from the URDF's ``<inertial>``
(zeros without one). A named link welded to a moving body by fixed (or locked) joints is moved
into the body's frame linearly (:mod:`lagcodegen.model.inertial`): the equations of motion stay
linear in the parameters, whatever the tree.

One job: choose, check, declare and place the parameters; :mod:`.urdf` builds the model.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import sympy as sp

from ..model.bodies import DYNAMIC_PARAMETERS
from ..util import excerpt
from .urdfxml import RobotDescription, URDFError


def chosen_links(robot: RobotDescription, tree: list, option: bool | Sequence[str]) -> list[str]:
    """The links whose inertials become parameters, in the tree's order: True: the link of every
    moving body (the child of each movable joint); a name or a list of names: those (each must
    move: a link fixed to the world has no effect on the equations); False: none."""
    if option is False or option is None:
        return []
    moving = [link for b in tree for link, _, _ in b.welded]
    if option is True:
        return [b.joint.child for b in tree]
    names = [option] if isinstance(option, str) else option
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise URDFError(f"inertial_parameters must be True, False or a list of link names, got {excerpt(option)}",
                        robot.filename, None, "")
    for n in names:
        if n not in robot.links:
            raise URDFError(f"inertial_parameters: no link named {n!r} (links: {', '.join(robot.links)})",
                            robot.filename, None, "")
        if n not in moving:
            raise URDFError(f"inertial_parameters: link {n!r} is fixed to the world (it does not move): its "
                            "inertia has no effect on the equations of motion", robot.filename,
                            robot.links[n].line, f"link {n!r}")
    return [link for link in moving if link in set(names)]


def link_defaults(robot: RobotDescription, link: str) -> list[float]:
    """The link's dynamic parameters from its URDF ``<inertial>`` (in the link frame)."""
    inertial = robot.links[link].inertial
    if inertial is None:
        return [0.0] * 10
    m, c = float(inertial.mass), np.array(inertial.xyz, dtype=float)
    Io = inertial.inertia_in_link_frame() + m * (c @ c * np.eye(3) - np.outer(c, c))
    return [m, *(m * c), Io[0, 0], Io[0, 1], Io[1, 1], Io[0, 2], Io[1, 2], Io[2, 2]]


def declare(model, robot: RobotDescription, links: list[str], identifier) -> dict[str, list[sp.Symbol]]:
    """The parameters of ``links`` declared on ``model`` (``identifier(name)``: the link's name
    made an identifier): link -> its 10 symbols."""
    out = {}
    for link in links:
        ident = identifier(link)
        out[link] = [model.parameter(f"{ident}_{suffix}", value)
                     for suffix, value in zip(DYNAMIC_PARAMETERS, link_defaults(robot, link))]
    return out


def _moved(m, h, Io, R: np.ndarray, p: np.ndarray) -> tuple:
    """(m, h, I_o) moved from a frame at (R, p) in the body frame into the body frame (linear)."""
    if np.array_equal(R, np.eye(3)) and not np.any(p):
        return m, h, Io
    Rs, ps = sp.Matrix(R.tolist()), sp.Matrix(p.tolist())
    Rh = Rs * h
    I = Rs * Io * Rs.T - m * ps * ps.T - ps * Rh.T - Rh * ps.T + (m * (ps.T * ps)[0, 0]
                                                                   + 2 * (ps.T * Rh)[0, 0]) * sp.eye(3)
    return m, m * ps + Rh, I.applyfunc(sp.expand)


def body_parameters(robot: RobotDescription, body, params: dict) -> list | None:
    """The 10 dynamic parameters of a moving ``body`` (about its frame) when one of its links is
    in ``params`` (link -> symbols): the parameters of those, placed, plus the URDF's inertials
    of the others; None when none is (the body keeps its numbers: the model is as without the
    option)."""
    if not any(link in params for link, _, _ in body.welded):
        return None
    m, h, Io = sp.Integer(0), sp.zeros(3, 1), sp.zeros(3, 3)
    for link, R, p in body.welded:
        v = params[link] if link in params else [sp.Float(x) if x != 0 else sp.Integer(0)
                                                 for x in link_defaults(robot, link)]
        Ik = sp.Matrix([[v[4], v[5], v[7]], [v[5], v[6], v[8]], [v[7], v[8], v[9]]])
        mk, hk, Ik = _moved(v[0], sp.Matrix(v[1:4]), Ik, np.asarray(R, dtype=float), np.asarray(p, dtype=float))
        m, h, Io = m + mk, h + hk, Io + Ik
    return [m, h[0], h[1], h[2], Io[0, 0], Io[0, 1], Io[1, 1], Io[0, 2], Io[1, 2], Io[2, 2]]
