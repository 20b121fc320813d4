"""Ground contacts of a URDF robot's collision spheres: :func:`spheres`, :func:`sphere_contacts`.

One job: turn the ``<collision>`` spheres of a URDF's links (:class:`.urdfxml.Collision`: a
``<sphere radius>`` placed by the collision ``<origin xyz rpy>`` in the link frame) into the
ground-contact inequalities of a model loaded from the same file (:func:`.urdf.load`; the
public function is :func:`lagcodegen.modelfile.urdf.ground_contacts`, which places each link in
the model's tree), for a
:class:`~lagcodegen.theory.constraints.ConstrainedSystem`'s ``inequalities``.

Each sphere of radius r centred at c (a point fixed in its link) on the plane z = ``ground``
(normal +z, the world frame of the model) gives the gap

    g(q) = z(c(q)) - r - ground >= 0,

exact for a sphere on a plane whatever the link's orientation: the sphere's lowest point is
c - r e_z, at height z(c) - r. With ``tangent``, the slip velocity of the contact is that of
the link's material point touching the ground, u = v(c) + omega x (-r e_z), i.e.
(x(c)' - r omega_y, y(c)' + r omega_x) with omega the link's angular velocity in the world
frame (from R' R^T): a sphere rolling without slipping has u = 0. Links welded to a moving
body by ``fixed`` joints (a foot frame on a shank) place their spheres in that body's frame
through the welded placements, as :func:`.urdf.bodies` merges them.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import sympy as sp

from ..model.model import Model
from ..theory.constraints import Inequality
from ..util import excerpt
from .urdfxml import Collision, RobotDescription, URDFError

#: The ``tangent`` values of :func:`sphere_contacts` (and :func:`.urdf.ground_contacts`): None (frictionless), one world axis
#: (planar friction), both (3-D friction on the exact circular cone).
TANGENTS = (None, "x", "y", "xy")


def spheres(robot: RobotDescription, links: Sequence[str] | None = None) -> list[tuple[str, Collision]]:
    """The collision spheres of ``robot`` as (link name, :class:`Collision`), links and their
    collisions in file order; ``links``: only those links' (each must have at least one sphere).
    A sphere with a problem (a radius that is not a positive finite number, ...) is a
    :class:`URDFError` naming the file, the line and the link."""
    if links is None:
        chosen = list(robot.links)
    else:
        if isinstance(links, str):
            links = [links]
        chosen = list(links)
        for name in chosen:
            if not isinstance(name, str) or name not in robot.links:
                raise URDFError(f"ground_contacts: no link named {excerpt(name)} (links: "
                                f"{excerpt(', '.join(robot.links))})", robot.filename, None, "")
            link = robot.links[name]
            if not any(c.kind == "sphere" for c in link.collisions):
                kinds = sorted({c.kind or "no geometry" for c in link.collisions})
                raise URDFError(f"link {name!r} has no <collision> sphere (its collisions: "
                                f"{', '.join(kinds) if kinds else 'none'}); ground contacts are made of spheres",
                                robot.filename, link.line, f"link {name!r}")
    out = []
    for name in chosen:
        for c in robot.links[name].collisions:
            if c.kind == "sphere":
                out.append((name, c.check()))
    return out


def _slip(model: Model, link, center: sp.Matrix, radius: float) -> tuple[sp.Expr, sp.Expr]:
    """The world x and y slip velocity of the material point of ``link`` at the bottom of the
    sphere (centre ``center`` in the world, ``radius``): c' + omega x (-r e_z)."""
    R = link.rotation()
    Rd = R.applyfunc(model.time_derivative)
    W = Rd * R.T  # [omega]_x in the world frame
    wx, wy = W[2, 1], W[0, 2]
    return (model.time_derivative(center[0]) - radius * wy, model.time_derivative(center[1]) + radius * wx)


def sphere_contacts(model: Model, robot: RobotDescription, frames: dict, *, restitution: float, ground=0.0,
                    tangent: str | None = None, friction: float | None = None,
                    links: Sequence[str] | None = None) -> list[Inequality]:
    """The inequalities of :func:`lagcodegen.modelfile.urdf.ground_contacts` (its docstring),
    given ``frames``: URDF link -> (the model link it is welded to, or None for the fixed
    base; the link frame's rotation and origin in that link's frame; the link's name as an
    identifier, the prefix of its points' names)."""
    if tangent not in TANGENTS:
        raise URDFError(f"ground_contacts: tangent must be None, 'x', 'y' (one world axis: planar friction) or "
                        f"'xy' (3-D friction), got {excerpt(tangent)}", robot.filename, None, "")
    if friction is not None and tangent is None:
        raise URDFError("ground_contacts: friction needs a tangent direction ('x', 'y' or 'xy')", robot.filename,
                        None, "")
    if isinstance(ground, sp.Expr):
        ground_expr = ground
    elif isinstance(ground, (int, float, np.integer, np.floating)) and not isinstance(ground, bool) \
            and np.isfinite(ground):
        ground_expr = sp.Float(float(ground))
    else:
        raise URDFError(f"ground_contacts: ground must be a finite number or a model parameter, got "
                        f"{excerpt(ground)}", robot.filename, None, "")
    links_by_name = {lk.name: lk for lk in model.links}
    out = []
    counts: dict[str, int] = {}
    for lname, sphere in spheres(robot, links):
        body, R, p, ident = frames[lname]
        if body is None:
            if links is not None:
                raise URDFError(f"link {lname!r} is welded to the fixed base: its sphere cannot move (load the "
                                "robot with floating=True for a floating base)", robot.filename,
                                robot.links[lname].line, f"link {lname!r}")
            continue
        center = p + R @ np.array(sphere.xyz, dtype=float)
        k = counts.get(lname, 0)
        counts[lname] = k + 1
        pt = model.point_on(body, [sp.Float(float(x)) for x in center], f"{ident}_sphere_{k}")
        r = sp.Float(sphere.radius)
        gap = pt.position[2] - r - ground_expr
        tan = None
        if tangent is not None:
            slip = _slip(model, links_by_name[body], pt.position, r)
            tan = tuple(slip["xy".index(a)] for a in tangent)
            tan = tan[0] if len(tan) == 1 else tan
        out.append(Inequality(gap, restitution=restitution, tangent=tan, friction=friction))
    return out
