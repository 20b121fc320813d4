"""URDF robots as lagcodegen models: :func:`load` a file, :func:`loads` a string.

One job: turn the checked :class:`~lagcodegen.modelfile.urdfxml.RobotDescription` of a URDF file
into a :class:`~lagcodegen.model.Model` (or, with ``limits=True``, a
:class:`~lagcodegen.theory.constraints.ConstrainedSystem`).

What the model holds:

* one generalized coordinate per movable joint (``revolute``, ``continuous``, ``prismatic``),
  named after the joint: the angle (rad) about, or the displacement (m) along, the joint axis,
  zero at the joint's ``origin``; continuous joints are angles too (Pinocchio writes them as a
  (cos, sin) pair). Names are the URDF's with characters other than letters, digits and ``_``
  made ``_`` (two names that become one are an error); the coordinates come depth first from
  the root, siblings in file order;
* the bodies as links of a tree (``form="tree"``: :meth:`Model.link`, the placements and
  inertias of :mod:`lagcodegen.model.bodies`, evaluated along the tree by the derivation) or
  as rigid bodies whose world poses are multiplied out (``form="closed"``:
  :meth:`Model.rigid_body`, the same equations as closed forms, which grow fast with the
  number of joints);
* a fixed base (the root link does not move), or with ``floating=True`` a free joint
  ``root_joint`` between the world and the root in Pinocchio's free-flyer layout (q: x, y, z,
  qx, qy, qz, qw; v: the linear and angular velocity in the root's frame), before the URDF's
  joints in q and v; URDF ``floating`` joints become free joints too. ``rotation="ZYX"`` gives
  them Z-Y-X Euler angles instead (singular at pitch = +-pi/2);
* the links' inertials: mass, centre of mass and the inertia about it, turned from the axes of
  the inertial ``origin`` into the link's axes (I_link = R I R^T, R from its ``rpy``);
* links attached by ``fixed`` joints merged into their parent (masses added, centres of mass
  combined, inertias moved by the parallel-axis theorem), the placements of the joints
  beyond them composed;
* with ``inertial_parameters``, the inertials of the chosen links as run-time parameters (ten
  per link, the mass, first moments and inertia about the link frame: Pinocchio's dynamic
  parameters, defaults from the file; :mod:`.urdf_inertial`), the equations linear in them;
* gravity: the parameter ``g`` (default 9.81, or the norm of ``gravity``) along ``-z`` or
  along the direction of ``gravity``; ``gravity=(0, 0, 0)`` leaves it out;
* ``<dynamics damping=c>``: viscous joint damping, the Rayleigh dissipation D = c/2 q_i'^2
  (eq. 3.15), i.e. a generalized force -c q_i';
* ``<dynamics friction=f>`` (Coulomb friction): ``friction="ignore"`` (default) leaves it out
  with a warning naming the joints; ``friction="smooth"`` adds the generalized force
  Q_i = -f q_i' / sqrt(q_i'^2 + v_s^2) (a smooth sign function, ``v_s = friction_velocity``,
  default 1e-3 rad/s or m/s: |Q_i| is within 1 % of f once |q_i'| > 8 v_s);
* with ``limits=True``, the ``<limit lower upper>`` of each revolute and prismatic joint as two
  inequality constraints q_i - lower >= 0 and upper - q_i >= 0 (eq. 4.3; joints whose lower
  equals upper are left out), enforced as hard stops: a joint reaching its limit stops there
  (a plastic impact; ``limits=("stop", e)``: it rebounds with restitution e), rests against it
  while the load pushes into it, and leaves it when the stop's multiplier would pull
  (:func:`lagcodegen.compile_constrained` runs them on the impact driver); ``limits="monitor"``
  only locates them (a run ends at the first limit touched, as an event).

``lock={joint: position}`` holds joints fixed (merged like fixed joints at that position).

Refused with a :class:`~lagcodegen.modelfile.urdfxml.URDFError` naming the file and element:
``mimic`` joints with ``mimic="error"`` (by default they are driven by the joint they follow,
``mimic="independent"`` makes them coordinates of their own as Pinocchio's
``buildModelFromUrdf`` reads them by default, ``"coupled"`` holds them by holonomic constraints),
a mimic joint following a locked or later joint, a URDF without any movable joint. ``planar`` joints move in the
plane normal to their axis: coordinates ``<joint>_x``, ``<joint>_y``, ``<joint>_theta``
(:meth:`lagcodegen.model.bodies.Joint.planar`). Meshes,
visuals, materials, transmissions and Gazebo tags are ignored; the ``<collision>`` spheres give
ground contacts through :func:`ground_contacts` (:mod:`.urdf_contacts`).
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
import sympy as sp

from ..errors import ModelError
from ..util import excerpt
from ..model.bodies import ROTATIONS, Joint as Joint_, Placement
from ..model.model import Model
from ..theory.constraints import ConstrainedSystem, Inequality
from . import urdf_inertial as _inertial
from .urdf_contacts import TANGENTS, sphere_contacts, spheres  # noqa: F401
from .urdfxml import (MAX_BYTES, ONE_DOF, Inertial, Joint, RobotDescription, URDFError, parse, read,  # noqa: F401
                      rpy_matrix)

__all__ = ["load", "loads", "build", "bodies", "ground_contacts", "spheres", "link_frames", "TANGENTS", "DEFAULT_FORM",
           "FORMS", "FRICTION", "MIMIC", "URDFError", "RobotDescription", "parse", "read"]

#: What :func:`build` does with Coulomb friction (``<dynamics friction>``).
FRICTION = ("ignore", "smooth")
#: How :func:`build` states the bodies: "tree" as links (:meth:`Model.link`, evaluated along the
#: tree), "closed" as rigid bodies with their world poses multiplied out (:meth:`Model.rigid_body`).
FORMS = ("tree", "closed")
#: The form :func:`load` uses unless told.
DEFAULT_FORM = "tree"
#: What :func:`build` does with ``<mimic>`` joints.
MIMIC = ("driven", "error", "independent", "coupled")


def _locked(robot: RobotDescription, lock) -> dict[str, float]:
    """The joints to hold fixed, name -> position (a bare name: at 0)."""
    if isinstance(lock, str):
        lock = [lock]
    items = lock.items() if isinstance(lock, Mapping) else ((name, 0.0) for name in lock)
    out = {}
    for jname, value in items:
        j = robot.joints.get(jname)
        if j is None:
            raise URDFError(f"lock: no joint named {jname!r}", robot.filename, None, "")
        if j.type not in ONE_DOF:
            raise URDFError(f"lock: joint {jname!r} is {j.type}, not revolute, continuous or prismatic",
                            robot.filename, j.line, f"joint {jname!r}")
        try:
            out[jname] = float(value)
        except (TypeError, ValueError):
            raise URDFError(f"lock: position of joint {jname!r} must be a number, got {excerpt(value)}",
                            robot.filename, j.line, f"joint {jname!r}") from None
    return out


@dataclass(frozen=True)
class Body:
    """A moving body of the tree after merging fixed joints: the movable ``joint`` that carries
    it, its ``parent`` body (None: the fixed base), the joint frame's placement (``rotation``,
    ``xyz``) in the parent body's frame, and the merged inertial in the body's frame."""

    joint: Joint
    parent: str | None
    rotation: np.ndarray
    xyz: np.ndarray
    mass: float
    com: np.ndarray
    inertia: np.ndarray  # about the centre of mass, body axes
    #: the links merged into the body, (name, R, p) of each link frame in the body frame
    welded: tuple = ()


def _merge(pieces: list[tuple[float, np.ndarray, np.ndarray]]) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia about it) of rigidly joined (mass, com, inertia) pieces:
    masses add, the centre of mass is their mean, the parallel-axis theorem moves each inertia."""
    mass = sum(m for m, _, _ in pieces)
    if mass == 0:
        return 0.0, np.zeros(3), sum((I for _, _, I in pieces), np.zeros((3, 3)))
    com = sum(m * c for m, c, _ in pieces) / mass
    inertia = np.zeros((3, 3))
    for m, c, I in pieces:
        d = c - com
        inertia += I + m * (d @ d * np.eye(3) - np.outer(d, d))
    return mass, com, (inertia + inertia.T) / 2


def _axis_rotation(axis, angle: float) -> np.ndarray:
    u = np.array(axis, dtype=float)
    ux = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.cos(angle) * np.eye(3) + np.sin(angle) * ux + (1 - np.cos(angle)) * np.outer(u, u)


def bodies(robot: RobotDescription, locked: dict | None = None, floating: str | None = None) -> list[Body]:
    """The moving bodies of ``robot``, fixed joints (and the ``locked`` joints, name -> position)
    merged, depth first from the root; with ``floating``, the root (and what is welded to it)
    is the first body, on a free joint of that name."""
    out: list[Body] = []
    locked = locked or {}

    def pose(j: Joint) -> tuple[np.ndarray, np.ndarray]:
        R, p = rpy_matrix(j.rpy), np.array(j.xyz, dtype=float)
        if j.name in locked and j.type == "prismatic":
            p = p + R @ np.array(j.axis) * locked[j.name]
        elif j.name in locked:
            R = R @ _axis_rotation(j.axis, locked[j.name])
        return R, p

    def inertial_piece(link: str, R: np.ndarray, p: np.ndarray):
        inertial: Inertial | None = robot.links[link].inertial
        if inertial is None or (inertial.mass == 0 and not np.any(inertial.inertia)):
            return None
        return (inertial.mass, p + R @ np.array(inertial.xyz, dtype=float),
                R @ inertial.inertia_in_link_frame() @ R.T)

    def walk(body_link: str, joint: Joint | None, parent: str | None, R0: np.ndarray, p0: np.ndarray) -> list:
        # the links welded to body_link by fixed joints, with their poses in the body frame
        welded = [(body_link, np.eye(3), np.zeros(3))]
        movable: list[tuple[Joint, np.ndarray, np.ndarray]] = []
        k = 0
        while k < len(welded):
            link, R, p = welded[k]
            k += 1
            for j in robot.children(link):
                Rj, pj = pose(j)
                if j.type == "fixed" or j.name in locked:
                    welded.append((j.child, R @ Rj, p + R @ pj))
                else:
                    movable.append((j, R @ Rj, p + R @ pj))
        if joint is not None:
            pieces = [pc for pc in (inertial_piece(link, R, p) for link, R, p in welded) if pc is not None]
            mass, com, inertia = _merge(pieces) if pieces else (0.0, np.zeros(3), np.zeros((3, 3)))
            out.append(Body(joint, parent, R0, p0, mass, com, inertia, tuple(welded)))
        return [(j.child, j, body_link if joint is not None else None, R, p) for j, R, p in movable]

    # Depth first, children in file order, with a stack (a chain of thousands of links is deeper
    # than Python's recursion limit).
    root_joint = None if floating is None else Joint(floating, "floating", "", robot.root)
    stack = [(robot.root, root_joint, None, np.eye(3), np.zeros(3))]
    while stack:
        stack += reversed(walk(*stack.pop()))
    return out


def _identifier(name: str) -> str:
    ident = re.sub(r"\W", "_", name)
    return ident if ident.isidentifier() else f"robot_{ident}"


def _names(robot: RobotDescription, tree: list[Body]) -> dict[str, str]:
    """Identifiers for the joints (coordinate names) and links of ``tree``: the URDF names, with
    characters other than letters, digits and _ replaced by _."""
    out: dict[str, str] = {}
    taken: dict[str, str] = {}
    for b in tree:
        for original in (b.joint.name, b.joint.child):
            ident = _identifier(original)
            if taken.get(ident, original) != original:
                raise URDFError(f"names {taken[ident]!r} and {original!r} both become the identifier {ident!r}",
                                robot.filename, b.joint.line, f"joint {b.joint.name!r}")
            taken[ident] = original
            out[original] = ident
    return out


def _links(model: Model, tree: list[Body], names: dict[str, str], rotation: str = "quaternion",
           robot: RobotDescription | None = None, params: dict | None = None, driven: bool = False
           ) -> dict[str, sp.Symbol]:
    """The bodies as a tree of links (:meth:`Model.link`); the coordinate of each joint. The
    bodies holding a link of ``params`` (link -> its dynamic-parameter symbols) take their
    dynamic parameters (:func:`.urdf_inertial.body_parameters`)."""
    coords = {}
    kinds = {"revolute": Joint_.revolute, "continuous": Joint_.continuous, "prismatic": Joint_.prismatic,
             "planar": Joint_.planar}
    for b in tree:
        j = b.joint
        I = b.inertia
        joint = (Joint_.free(names[j.name], rotation=rotation) if j.type == "floating"
                 else kinds[j.type](names[j.name], tuple(float(a) for a in j.axis)))
        if driven and j.mimic is not None:  # mimic="driven": no coordinate, its leader's times the gain
            if j.mimic.joint not in coords:
                raise URDFError(f"mimic joint {j.name!r} follows {j.mimic.joint!r}, which is locked, fixed or comes "
                                "after it in the tree: lock both, or use mimic='independent'", robot.filename if robot
                                else "<urdf>", j.line, f"joint {j.name!r}")
            joint = joint.mimicking(coords[j.mimic.joint].name, j.mimic.multiplier, j.mimic.offset)
        dyn = _inertial.body_parameters(robot, b, params) if params else None
        if dyn is not None:
            link = model.link(names[j.child], parent=None if b.parent is None else names[b.parent], joint=joint,
                              origin=Placement(xyz=tuple(float(x) for x in b.xyz), rotation=b.rotation.tolist()),
                              dynamic_parameters=dyn)
            coords[j.name] = link.coordinates[0]
            continue
        link = model.link(names[j.child], parent=None if b.parent is None else names[b.parent], joint=joint,
                          origin=Placement(xyz=tuple(float(x) for x in b.xyz), rotation=b.rotation.tolist()),
                          mass=float(b.mass), com=tuple(float(x) for x in b.com),
                          inertia=(I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]))
        coords[j.name] = link.coordinates[0]
    return coords


def _rigid_bodies(model: Model, tree: list[Body], names: dict[str, str], rotation: str = "quaternion",
                  driven: bool = False) -> dict[str, sp.Symbol]:
    """The bodies as closed-form rigid bodies (:meth:`Model.rigid_body`): the world pose of each
    (:meth:`Link.pose` of the same tree stated as links in a scratch model, whose coordinates
    are the same symbols) multiplied out; the coordinate of each joint."""
    scratch = Model(model.name)
    _links(scratch, tree, names, rotation, driven=driven)
    for c in scratch.coords:
        model.coordinate(c.name)
    if scratch.general:  # quaternion joints: their speeds and kinematic equations
        model.generalized_speeds([v.name for v in scratch.velocities], scratch.kinematics)
    coords = {}
    for b, link in zip(tree, scratch.links):
        coords[b.joint.name] = link.coordinates[0]
        if b.mass > 0 or np.any(b.inertia):
            model.rigid_body(names[b.joint.child], link.mass, link.inertia, link.com_position(), link.rotation())
    return coords


@dataclass(frozen=True)
class LoadOptions:
    """The options of :func:`load`, :func:`loads` and :func:`build`, each described at
    :func:`load`; given as keywords, checked by :func:`build`."""

    name: str | None = None
    gravity: Sequence[float] = (0.0, 0.0, -9.81)
    limits: bool | str | tuple = False
    friction: str = "ignore"
    friction_velocity: float = 1e-3
    lock: Mapping[str, float] | Sequence[str] = ()
    mimic: str = "driven"
    form: str = DEFAULT_FORM
    floating: bool | str = False
    rotation: str = "quaternion"
    inertial_parameters: bool | Sequence[str] = False


def load_options(robot: RobotDescription, options: Mapping) -> LoadOptions:
    """``options`` (keywords of :func:`load`) as :class:`LoadOptions`; an unknown one is a
    URDFError naming it and the known ones."""
    known = LoadOptions.__dataclass_fields__
    unknown = [k for k in options if k not in known]
    if unknown:
        raise URDFError(f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(map(repr, unknown))} (known: "
                        f"{', '.join(known)})", robot.filename, None, "")
    return LoadOptions(**options)


def build(robot: RobotDescription, **options) -> Model | ConstrainedSystem:
    """The :class:`Model` of a parsed URDF robot (see the module docstring; ``options``: the
    keywords of :func:`load`, :class:`LoadOptions`)."""
    o = load_options(robot, options)
    name, gravity, limits, friction, friction_velocity = o.name, o.gravity, o.limits, o.friction, o.friction_velocity
    lock, mimic, form, floating, rotation = o.lock, o.mimic, o.form, o.floating, o.rotation
    inertial_parameters = o.inertial_parameters
    root_joint = "root_joint" if floating is True else (floating or None)
    if root_joint is not None and (not isinstance(root_joint, str) or not root_joint.isidentifier()
                                   or root_joint in robot.joints):
        raise URDFError(f"floating must be True or the name of the free joint (an identifier that names no joint of "
                        f"the robot), got {excerpt(floating)}", robot.filename, None, "")
    if form not in FORMS:
        raise URDFError(f"form must be one of {', '.join(FORMS)}, got {excerpt(form)}", robot.filename, None, "")
    if rotation not in ROTATIONS:
        raise URDFError(f"rotation must be one of {', '.join(ROTATIONS)}, got {excerpt(rotation)}", robot.filename,
                        None, "")
    if mimic not in MIMIC:
        raise URDFError(f"mimic must be one of {', '.join(MIMIC)}, got {excerpt(mimic)}", robot.filename, None, "")
    locked = _locked(robot, lock)
    if friction not in FRICTION:
        raise URDFError(f"friction must be one of {', '.join(FRICTION)}, got {excerpt(friction)}", robot.filename,
                        None, "")
    if not (isinstance(friction_velocity, (int, float)) and friction_velocity > 0):
        raise URDFError(f"friction_velocity must be a positive number, got {excerpt(friction_velocity)}",
                        robot.filename, None, "")
    gvec = np.array(gravity, dtype=float)
    if gvec.shape != (3,) or not np.all(np.isfinite(gvec)):
        raise URDFError(f"gravity must be 3 finite numbers, got {excerpt(gravity)}", robot.filename, None, "")

    def err(j: Joint, message: str) -> URDFError:
        return URDFError(message, robot.filename, j.line, f"joint {j.name!r}")

    for jname in robot.order:
        j = robot.joints[jname]
        if j.name in locked:
            continue
        if j.mimic is not None and mimic == "error":
            raise err(j, f"mimic joints are not supported: {j.name!r} follows {j.mimic.joint!r} "
                         f"({j.mimic.multiplier} * {j.mimic.joint} + {j.mimic.offset}), a constraint rather than a "
                         "coordinate; pass mimic='coupled' (the coupling as a holonomic constraint: a "
                         "ConstrainedSystem, e.g. compile_constrained(system, 'minimal')), mimic='independent' (the "
                         "joint becomes a coordinate of its own, as "
                         f"Pinocchio reads it by default), lock={{{j.name!r}: <position>}}, or write the coupling "
                         "as a holonomic constraint of a ConstrainedSystem")
    tree = bodies(robot, locked, root_joint)
    if not tree:
        raise URDFError("the robot has no movable joint (revolute, continuous or prismatic): nothing moves",
                        robot.filename, None, f"robot {robot.name!r}")

    model = Model(_identifier(name or robot.name))
    g = None
    if np.any(gvec != 0):
        g = model.parameter("gravity_g" if "g" in robot.joints else "g", float(np.linalg.norm(gvec)))
    names = _names(robot, tree)
    chosen = _inertial.chosen_links(robot, tree, inertial_parameters)
    if chosen and form != "tree":
        raise URDFError("inertial_parameters need form='tree' (the closed form's equations would not be linear in "
                        "them)", robot.filename, None, "")
    try:
        params = _inertial.declare(model, robot, chosen, _identifier)
        coords = (_links(model, tree, names, rotation, robot, params, mimic == "driven") if form == "tree"
                  else _rigid_bodies(model, tree, names, rotation, mimic == "driven"))
    except ModelError as exc:  # a name the model refuses (a reserved word, a clash)
        raise URDFError(str(exc), robot.filename, None, f"robot {robot.name!r}") from None
    if g is not None:
        model.gravity(g, up=[sp.Float(float(x)) for x in -gvec / np.linalg.norm(gvec)])

    damping = [(b.joint, coords[b.joint.name]) for b in tree
               if b.joint.dynamics is not None and b.joint.dynamics.damping > 0]
    if damping:
        # a driven mimic joint's q is gain q_leader + offset: its rate gain q_leader'
        model.dissipation(sum((sp.Float(j.dynamics.damping) / 2 * model.time_derivative(q) ** 2 for j, q in damping),
                              sp.Integer(0)), label="joint damping")
    rubbing = [(b.joint, coords[b.joint.name]) for b in tree
               if b.joint.dynamics is not None and b.joint.dynamics.friction > 0]
    if rubbing and friction == "ignore":
        warnings.warn(f"{robot.filename}: Coulomb friction of joint(s) {', '.join(j.name for j, _ in rubbing)} "
                      "ignored (pass friction='smooth' to model it)", stacklevel=3)
    elif rubbing:
        vs = sp.Float(friction_velocity)
        for j, q in rubbing:
            v = model.time_derivative(q)
            leader = q if isinstance(q, sp.Symbol) else next(iter(q.free_symbols & set(model.coords)))
            model.generalized_force(leader, -sp.diff(q, leader) * sp.Float(j.dynamics.friction) * v
                                    / sp.sqrt(v**2 + vs**2), label=f"Coulomb friction of {j.name}")
    model.validate()
    coupled = _couplings(robot, tree, coords) if mimic == "coupled" else []
    if limits is False:
        return ConstrainedSystem(model, holonomic=coupled) if coupled else model
    stop = _limit_kind(limits, robot)
    inequalities = []
    for b in tree:
        j, q = b.joint, coords[b.joint.name]
        lim = j.limit
        if j.type in ("continuous", "planar", "floating") or lim is None or lim.lower is None or lim.upper is None \
                or lim.lower == lim.upper:
            continue
        rows = [q - sp.Float(lim.lower), sp.Float(lim.upper) - q]
        inequalities += rows if stop is None else [Inequality(g, restitution=stop) for g in rows]
    return ConstrainedSystem(model, holonomic=coupled, inequalities=inequalities)


def _couplings(robot: RobotDescription, tree: list[Body], coords: dict) -> list:
    """The holonomic constraints q_j - (multiplier q_k + offset) = 0 of the ``<mimic>`` joints j
    of ``tree`` following joint k (eq. 4.1); a mimic joint following a locked joint is refused."""
    rows = []
    for b in tree:
        j = b.joint
        if j.mimic is None:
            continue
        if j.mimic.joint not in coords:
            raise URDFError(f"mimic joint {j.name!r} follows {j.mimic.joint!r}, which is locked or fixed: lock "
                            f"{j.name!r} too", robot.filename, j.line, f"joint {j.name!r}")
        rows.append(coords[j.name] - (sp.Float(j.mimic.multiplier) * coords[j.mimic.joint] + sp.Float(j.mimic.offset)))
    return rows


#: How ``limits=`` reads: True or "stop" (hard stops, a plastic impact: restitution 0),
#: ``("stop", e)`` (hard stops with restitution e), "monitor" (inequalities located, not enforced).
LIMIT_KINDS = ("stop", "monitor")


def _limit_kind(limits, robot: RobotDescription) -> float | None:
    """The restitution of the joint stops ``limits`` asks for, or None for monitored limits."""
    if limits is True or limits == "stop":
        return 0.0
    if limits == "monitor":
        return None
    if isinstance(limits, tuple) and len(limits) == 2 and limits[0] == "stop" and isinstance(limits[1], (int, float)) \
            and not isinstance(limits[1], bool) and 0.0 <= float(limits[1]) <= 1.0:
        return float(limits[1])
    raise URDFError(f"limits must be False, True (or 'stop': hard stops), ('stop', restitution in [0, 1]) or "
                    f"'monitor', got {excerpt(limits)}", robot.filename, None, "")


def load(path: str | os.PathLike, *, max_bytes: int | None = MAX_BYTES, **options) -> Model | ConstrainedSystem:
    """The :class:`Model` of the URDF file at ``path`` (a :class:`ConstrainedSystem` with
    ``limits=True``). The options (keywords, :class:`LoadOptions`):

    ``name``: the model's name (default: the ``<robot name>``, made an identifier);
    ``gravity``: the gravitational acceleration vector in the root link's frame (m/s^2);
    ``limits``: joint limits as inequality constraints (eq. 4.3): True (or "stop") hard stops,
    ``("stop", e)`` stops with restitution e, "monitor" located only (module docstring);
    ``friction``, ``friction_velocity``: Coulomb friction, see the module docstring;
    ``lock``: joints held fixed, as ``{name: position}`` or names (at 0): merged like fixed
    joints (e.g. a gripper's fingers);
    ``mimic``: ``"driven"`` (default) makes each ``<mimic>`` joint what it is, driven by the
    joint it follows (no coordinate of its own, its angle multiplier q_k + offset: Pinocchio's
    ``mimic=True`` layout; :meth:`lagcodegen.model.bodies.Joint.mimicking`), ``"error"`` refuses
    them, ``"coupled"`` keeps each a
    coordinate held to its joint by the holonomic constraint q = multiplier q_k + offset (a
    :class:`ConstrainedSystem`; minimal coordinates eliminate it, as Pinocchio's ``mimic=True``
    does), ``"independent"`` makes them
    coordinates of their own (Pinocchio's default reading);
    ``form``: ``"tree"`` states the bodies as links of a tree (:meth:`Model.link`),
    ``"closed"`` as rigid bodies whose world poses are multiplied out (:meth:`Model.rigid_body`:
    the same equations, but closed forms that grow fast with the number of joints); default
    :data:`DEFAULT_FORM`;
    ``floating``: True puts the root link on a free joint ``root_joint`` (a string names it) in
    Pinocchio's free-flyer layout: coordinates ``<name>_x, _y, _z`` (the root frame's origin in
    the world) and the quaternion ``<name>_qx, _qy, _qz, _qw``, speeds ``<name>_vx, _vy, _vz,
    _wx, _wy, _wz`` (linear and angular velocity in the root's frame), then the URDF's joints
    (:meth:`lagcodegen.model.bodies.Joint.free`); default False: the root is fixed to the world;
    ``rotation``: "quaternion" (default) or "ZYX" (the free joints' rotation as Z-Y-X Euler
    angles ``<name>_yaw, _pitch, _roll``, their rates the speeds; singular at pitch = +-pi/2);
    ``inertial_parameters``: True makes the inertial of the link of every moving body (the
    child of each movable joint) run-time parameters, a list of link names those links' (links
    welded to a moving body by fixed joints too): ten per link, ``<link>_m``, ``<link>_mx``,
    ``_my``, ``_mz`` (the first moments m c), ``<link>_Ixx``, ``_Ixy``, ``_Iyy``, ``_Ixz``,
    ``_Iyz``, ``_Izz`` (the inertia about the link frame's origin, in its axes: Pinocchio's
    dynamic parameters), defaults from the URDF; the equations of motion are linear in them
    (:mod:`lagcodegen.modelfile.urdf_inertial`); default False (the URDF's numbers folded in);
    ``max_bytes``: a larger file is refused before it is read (:data:`MAX_BYTES`, 20 MiB,
    unless told; None: no cap).
    """
    return build(read(path, max_bytes=max_bytes), **options)


def loads(text: str | bytes, *, filename: str = "<string>", max_bytes: int | None = MAX_BYTES,
          **options) -> Model | ConstrainedSystem:
    """As :func:`load`, for URDF text (``filename`` names it in error messages)."""
    return build(parse(text, filename=filename, max_bytes=max_bytes), **options)


def link_frames(model: Model, robot: RobotDescription, lock=()) -> dict[str, tuple]:
    """Where each URDF link of ``robot`` sits in ``model`` (loaded from it by :func:`load`, with
    ``lock``): link name -> (the model link it is welded to, None for the fixed base; the link
    frame's rotation and origin in that link's frame; the link's name as an identifier). A
    model not loaded from ``robot`` (a body it lacks) is a :class:`URDFError`."""
    names = {lk.name for lk in model.links}
    if not names:
        raise URDFError(f"the model {model.name!r} has no links: load the robot with form='tree' (the default) to "
                        "place points on its links", robot.filename, None, "")
    floating = "root_joint" if _identifier(robot.root) in names else None
    out: dict = {}
    for b in bodies(robot, _locked(robot, lock), floating):
        body = _identifier(b.joint.child)
        if body not in names:
            raise URDFError(f"the model {model.name!r} has no link {body!r}: it was not loaded from this URDF with "
                            "these options (pass the lock= given to load)", robot.filename, b.joint.line,
                            f"link {b.joint.child!r}")
        for lname, R, p in b.welded:
            out[lname] = (body, np.asarray(R, dtype=float), np.asarray(p, dtype=float), _identifier(lname))
    for lname in robot.links:
        out.setdefault(lname, (None, np.eye(3), np.zeros(3), _identifier(lname)))  # welded to the fixed base
    return out


def ground_contacts(model: Model, urdf: str | os.PathLike | RobotDescription, *, restitution: float,
                    ground=0.0, tangent: str | None = None, friction: float | None = None,
                    links: Sequence[str] | None = None, lock=(), max_bytes: int | None = MAX_BYTES) -> list:
    """The ground contacts of the ``<collision>`` spheres of the URDF ``urdf`` (a path, or its
    :func:`read` description) on ``model``, loaded from it by :func:`load` (fixed or floating
    base, ``form="tree"``): a list of :class:`~lagcodegen.theory.constraints.Inequality`, one per sphere, for a
    :class:`ConstrainedSystem`'s ``inequalities``. Each is the exact gap of a sphere of radius r
    centred at c on the plane z = ``ground`` (normal +z),

        g(q) = z(c(q)) - r - ground >= 0,

    whatever the link's orientation (the sphere's lowest point is c - r e_z), with the
    coefficient of ``restitution``. The centres are declared on the model as points
    ``<link>_sphere_<k>``; spheres on links welded to a moving body by fixed joints (a foot
    frame on a shank) are placed in that body's frame.

    ``links``: the URDF links whose spheres to use (default: every link's; a link named without
    a sphere is an error); spheres on links welded to a fixed base are left out (they cannot
    move; naming such a link is an error). ``ground``: the plane's height (a number or a model
    parameter). ``tangent`` (:data:`TANGENTS`): None, frictionless; "x" or "y", a rough contact
    along that world axis (no slip, or Coulomb ``friction`` mu; planar); "xy", both axes, 3-D
    friction on the exact circular cone; the slip velocity is that of the link's material point
    touching the ground, (x(c)' - r omega_y, y(c)' + r omega_x) with omega the link's world
    angular velocity (zero for a sphere rolling without slipping). ``lock``: the ``lock=``
    given to :func:`load`. ``max_bytes``: as :func:`load`.

    Errors (:class:`URDFError`, naming the file, the line and the link): a link named that does
    not exist or has no sphere, a sphere whose radius is not a positive finite number (or whose
    collision origin does not parse), a model not loaded from this URDF.

    Example::

        m = urdf.load(path, floating=True)
        system = ConstrainedSystem(m, inequalities=urdf.ground_contacts(m, path, restitution=0.0))
    """
    if not isinstance(model, Model):
        raise URDFError(f"ground_contacts needs the lagcodegen Model loaded from the URDF, got "
                        f"{type(model).__name__}", str(getattr(urdf, "filename", urdf)), None, "")
    robot = urdf if isinstance(urdf, RobotDescription) else read(urdf, max_bytes=max_bytes)
    return sphere_contacts(model, robot, link_frames(model, robot, lock), restitution=restitution, ground=ground,
                           tangent=tangent, friction=friction, links=links)
