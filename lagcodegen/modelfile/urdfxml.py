"""URDF XML into a checked description of a kinematic tree (links, joints, inertials, limits).

One job: read a URDF file (the ROS Unified Robot Description Format) with the standard
library's expat parser and :class:`xml.etree.ElementTree.TreeBuilder`, never executing
anything, and return a :class:`RobotDescription` of plain frozen dataclasses whose every value
was checked. :mod:`lagcodegen.modelfile.urdf` turns it into a :class:`~lagcodegen.model.Model`.

What is read: ``<robot name>``; ``<link name>`` with its optional ``<inertial>`` (``<origin
xyz rpy>``, ``<mass value>``, ``<inertia ixx ixy ixz iyy iyz izz>``); ``<joint name type>``
with ``<parent link>``, ``<child link>``, ``<origin xyz rpy>``, ``<axis xyz>``, ``<limit lower
upper effort velocity>``, ``<dynamics damping friction>`` and ``<mimic joint multiplier
offset>``; each link's ``<collision>`` elements as :class:`Collision` (the geometry's kind, the
collision ``<origin xyz rpy>`` in the link frame, a ``<sphere radius>``'s radius: the spheres
serve ground contacts, :func:`lagcodegen.modelfile.urdf.ground_contacts`). Everything else
(``<visual>``, ``<material>``, ``<gazebo>``, ``<transmission>``, ...) is ignored.

A collision's problems (a radius that is not a positive finite number, an origin that does
not parse, no ``<geometry>``) do not stop the file from being read (the dynamics do not use
collisions; example-robot-data's quadruped.urdf has a xacro left-over ``${upper_leg_radius}``):
each is kept, located, in :attr:`Collision.problem` and raised when that collision is used.

Checks, each a :class:`URDFError` naming the file, the line, the element and the attribute:
numbers that do not parse or are not finite, vectors with the wrong number of entries, missing
required attributes (link and joint names, joint type, parent, child, mass value, the six
inertia entries), duplicate link or joint names, unknown joint types, a joint naming a link
that does not exist, a link that is the child of two joints, several root links (or none: a
cycle), joints that form a cycle, a zero joint axis, a negative mass, a negative damping or
friction, an inertia tensor with a negative eigenvalue (beyond :data:`INERTIA_RTOL` and
:data:`INERTIA_ATOL`; zero
eigenvalues are accepted: massless "dummy" links, point masses), ``lower > upper`` limits, a
``<mimic>`` naming a joint that does not exist, a file (or text) above :data:`MAX_BYTES`
(``max_bytes=`` moves or lifts the cap). A ``<robot>`` without a name takes the file's stem.

Conventions (URDF): ``rpy`` are fixed-axis roll, pitch, yaw, R = Rz(yaw) Ry(pitch) Rx(roll);
a joint's ``origin`` places the child link's frame (= the joint frame) in the parent link's
frame; the ``axis`` is given in the joint frame (default (1, 0, 0), normalized here); an
inertial's ``inertia`` is about the centre of mass in the axes of the inertial ``origin``.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np

from ..errors import ModelError
from ..util import FileProblem, excerpt, read_bounded

#: URDF joint types, all of which lagcodegen builds (floating: a free joint; planar: Joint.planar).
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: An inertia's smallest eigenvalue may be this much below zero, relative to its largest (the
#: rounding of inertias written with a few digits); a zero eigenvalue (a point mass, a thin rod) is
#: accepted, a negative one is an error.
INERTIA_RTOL = 1e-9
#: ... and this much in kg m^2 (entries written as 1e-35 by exporters).
INERTIA_ATOL = 1e-18
#: Joint types with one coordinate along or about the axis.
ONE_DOF = ("revolute", "continuous", "prismatic")
#: The largest URDF read or parsed unless told (``max_bytes=``), in bytes: 20 MiB, far above
#: real robots (Panda, ANYmal, Solo: tens of kB; meshes are separate files) and below what
#: takes seconds and hundreds of MB to parse (a 50 MB file: 12.5 s, 846 MB).
MAX_BYTES = 20 * 2**20


class URDFError(ModelError):
    """A problem in a URDF file. ``filename``, ``line`` (or None) and ``element`` say where."""

    def __init__(self, message: str, filename: str, line: int | None, element: str):
        self.filename = filename
        self.line = line
        self.element = element
        where = f"{filename}:{line}" if line else filename
        super().__init__(message, location=f"{where}: {element}" if element else where)


@dataclass(frozen=True)
class Inertial:
    """A link's mass, centre of mass ``xyz`` and inertia frame ``rpy`` (in the link frame), and
    the inertia about the centre of mass in that frame, as a symmetric 3x3 tuple of rows."""

    mass: float
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    def inertia_in_link_frame(self) -> np.ndarray:
        """The inertia about the centre of mass in the link's axes: R I R^T, R = rpy_matrix(rpy)."""
        R = rpy_matrix(self.rpy)
        I = R @ np.array(self.inertia, dtype=float) @ R.T
        return (I + I.T) / 2


#: The geometries of a URDF ``<collision>``: each collision is kept with its kind (only spheres
#: are used, by ground contacts); "" when it has none or another one.
GEOMETRIES = ("sphere", "box", "cylinder", "capsule", "mesh")


@dataclass(frozen=True)
class Collision:
    """A link's ``<collision>``: the ``kind`` of its geometry (:data:`GEOMETRIES`, or "" for none
    or an unknown one), its ``<origin>`` (``xyz``, ``rpy``: the geometry's frame in the link
    frame), a sphere's ``radius`` (None for the other kinds), the collision's ``name`` attribute
    (or None), its ``line``, and ``problem``: None, or why it cannot be used (a sphere radius
    that is not a positive finite number, an origin that does not parse, no ``<geometry>``), a
    :class:`URDFError` raised when the collision is used (:meth:`check`)."""

    kind: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float | None = None
    name: str | None = None
    line: int | None = None
    problem: URDFError | None = field(default=None, compare=False)

    def check(self) -> "Collision":
        """The collision itself, or its :attr:`problem` raised."""
        if self.problem is not None:
            raise self.problem
        return self


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial | None
    line: int | None = None
    #: the link's ``<collision>`` elements, in file order
    collisions: tuple = ()


@dataclass(frozen=True)
class Limit:
    lower: float | None
    upper: float | None
    effort: float | None = None
    velocity: float | None = None


@dataclass(frozen=True)
class Dynamics:
    damping: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True)
class Mimic:
    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Joint:
    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    limit: Limit | None = None
    dynamics: Dynamics | None = None
    mimic: Mimic | None = None
    line: int | None = None


@dataclass(frozen=True)
class RobotDescription:
    """A checked URDF tree: ``links`` and ``joints`` by name (file order), ``root`` the one link
    that is no joint's child, ``order`` the joints depth first from the root (children in file
    order), ``filename`` the file it came from."""

    name: str
    links: dict
    joints: dict
    root: str
    order: tuple
    filename: str = "<string>"
    parent_joint: dict = field(default_factory=dict)  # link name -> joint name (every link but the root)

    def children(self, link: str) -> list[Joint]:
        """The joints whose parent is ``link``, in file order (an index built on the first call:
        constant time per call after it)."""
        index = self.__dict__.get("_children")
        if index is None:
            index = {}
            for j in self.joints.values():
                index.setdefault(j.parent, []).append(j)
            object.__setattr__(self, "_children", index)  # a cache: the description stays as frozen
        return list(index.get(link, ()))


def rpy_matrix(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), URDF's fixed-axis roll-pitch-yaw."""
    r, p, y = rpy
    cr, sr, cp, sp_, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp_ * sr - sy * cr, cy * sp_ * cr + sy * sr],
                     [sy * cp, sy * sp_ * sr + cy * cr, sy * sp_ * cr - cy * sr],
                     [-sp_, cp * sr, cp * cr]])


# ---------------------------------------------------------------------------- XML
def _read_tree(text: bytes, filename: str) -> tuple[ET.Element, dict]:
    """The element tree of ``text`` and each element's line, parsed by expat (no DTD, no
    external entities)."""
    builder = ET.TreeBuilder()
    lines: dict = {}
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)

    def start(tag, attrs):
        lines[builder.start(tag, attrs)] = parser.CurrentLineNumber

    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    try:
        parser.Parse(text, True)
    except expat.ExpatError as exc:
        raise URDFError(f"not well-formed XML: {expat.ErrorString(exc.code)} (column {exc.offset + 1})",
                        filename, exc.lineno, "") from None
    return builder.close(), lines


class _Reader:
    """Typed values of elements and attributes, with located errors."""

    def __init__(self, filename: str, lines: dict):
        self.filename = filename
        self.lines = lines

    def error(self, el: ET.Element | None, what: str, message: str) -> URDFError:
        return URDFError(message, self.filename, self.lines.get(el) if el is not None else None, what)

    def text(self, el: ET.Element, attr: str, what: str) -> str:
        value = el.get(attr)
        if value is None or not value.strip():
            raise self.error(el, what, f"missing attribute {attr!r}" if value is None else f"empty attribute {attr!r}")
        return value.strip()

    def number(self, el: ET.Element, attr: str, what: str, default: float | None = None) -> float | None:
        value = el.get(attr)
        if value is None:
            if default is None:
                raise self.error(el, what, f"missing attribute {attr!r}")
            return default
        return self._float(el, attr, what, value)

    def optional(self, el: ET.Element, attr: str, what: str) -> float | None:
        value = el.get(attr)
        return None if value is None else self._float(el, attr, what, value)

    def _float(self, el, attr, what, value: str) -> float:
        whole = el.get(attr)
        token = "" if value.strip() == whole.strip() else f": {excerpt(value)}"
        try:
            x = float(value)
        except ValueError:
            raise self.error(el, what, f"attribute {attr}={excerpt(whole)}{token} is not a number") from None
        if not math.isfinite(x):
            raise self.error(el, what, f"attribute {attr}={excerpt(whole)}{token} is not finite")
        return x

    def vector(self, el: ET.Element | None, attr: str, what: str, default) -> tuple[float, float, float]:
        if el is None or el.get(attr) is None:
            return tuple(default)
        value = el.get(attr)
        parts = value.split()
        if len(parts) != 3:
            raise self.error(el, what, f"attribute {attr}={excerpt(value)} needs 3 numbers, has {len(parts)}")
        return tuple(self._float(el, attr, what, p) for p in parts)

    def one(self, parent: ET.Element, tag: str, what: str, required: bool = False) -> ET.Element | None:
        found = parent.findall(tag)
        if len(found) > 1:
            raise self.error(found[1], what, f"<{tag}> given {len(found)} times")
        if not found:
            if required:
                raise self.error(parent, what, f"missing <{tag}> element")
            return None
        return found[0]


# ---------------------------------------------------------------------------- elements
def _inertial(r: _Reader, el: ET.Element, link: str) -> Inertial:
    what = f"link {link!r} <inertial>"
    origin = r.one(el, "origin", what)
    xyz = r.vector(origin, "xyz", f"{what} <origin>", (0, 0, 0))
    rpy = r.vector(origin, "rpy", f"{what} <origin>", (0, 0, 0))
    mass_el = r.one(el, "mass", what, required=True)
    mass = r.number(mass_el, "value", f"{what} <mass>")
    if mass < 0:
        raise r.error(mass_el, f"{what} <mass>", f"negative mass value={mass!r}")
    inertia_el = r.one(el, "inertia", what, required=True)
    w = f"{what} <inertia>"
    ixx, ixy, ixz, iyy, iyz, izz = (r.number(inertia_el, a, w) for a in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    I = ((ixx, ixy, ixz), (ixy, iyy, iyz), (ixz, iyz, izz))
    eig = np.linalg.eigvalsh(np.array(I, dtype=float))
    if eig[0] < -(INERTIA_RTOL * abs(eig[-1]) + INERTIA_ATOL):
        raise r.error(inertia_el, w, f"inertia (ixx={ixx}, ixy={ixy}, ixz={ixz}, iyy={iyy}, iyz={iyz}, izz={izz}) is "
                                     "not positive definite: it has the negative eigenvalue "
                                     f"{eig[0]:.6g} (eigenvalues {', '.join(f'{e:.6g}' for e in eig)})")
    return Inertial(mass, xyz, rpy, I)


def _collision(r: _Reader, el: ET.Element, link: str) -> Collision:
    """A ``<collision>`` of ``link``; a problem with it is kept, not raised (:class:`Collision`).
    The kind is read first, so that a sphere with a bad origin is still a sphere (its problem
    raised when the spheres are used)."""
    what = f"link {link!r} <collision>"
    name, line = el.get("name"), r.lines.get(el)
    geometries = el.findall("geometry")
    shapes = list(geometries[0]) if geometries else []
    kind = shapes[0].tag if len(geometries) == 1 and len(shapes) == 1 and shapes[0].tag in GEOMETRIES else ""
    xyz, rpy, radius = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), None
    try:
        origin = r.one(el, "origin", what)
        xyz = r.vector(origin, "xyz", f"{what} <origin>", (0, 0, 0))
        rpy = r.vector(origin, "rpy", f"{what} <origin>", (0, 0, 0))
        geometry = r.one(el, "geometry", what, required=True)
        if len(shapes) != 1:
            raise r.error(geometry, f"{what} <geometry>", f"<geometry> has {len(shapes)} shapes, a collision has one")
        if kind == "sphere":
            shape = shapes[0]
            radius = r.number(shape, "radius", f"{what} <sphere>")
            if not radius > 0:
                raise r.error(shape, f"{what} <sphere>", f"sphere radius={shape.get('radius')!r} is not positive")
    except URDFError as problem:
        return Collision(kind, xyz, rpy, None, name, line, problem)
    return Collision(kind, xyz, rpy, radius, name, line)


def _joint(r: _Reader, el: ET.Element) -> Joint:
    name = r.text(el, "name", "<joint>")
    what = f"joint {name!r}"
    jtype = r.text(el, "type", what)
    if jtype not in JOINT_TYPES:
        raise r.error(el, what, f"unknown joint type {jtype!r} (URDF types: {', '.join(JOINT_TYPES)})")
    parent_el = r.one(el, "parent", what, required=True)
    child_el = r.one(el, "child", what, required=True)
    parent = r.text(parent_el, "link", f"{what} <parent>")
    child = r.text(child_el, "link", f"{what} <child>")
    origin = r.one(el, "origin", what)
    xyz = r.vector(origin, "xyz", f"{what} <origin>", (0, 0, 0))
    rpy = r.vector(origin, "rpy", f"{what} <origin>", (0, 0, 0))
    axis_el = r.one(el, "axis", what)
    axis = r.vector(axis_el, "xyz", f"{what} <axis>", (1, 0, 0))
    norm = math.sqrt(sum(a * a for a in axis))
    if jtype in ONE_DOF:
        if norm == 0:
            raise r.error(axis_el, f"{what} <axis>", f"axis xyz={axis_el.get('xyz')!r} is zero")
        axis = tuple(a / norm for a in axis)
    limit = None
    limit_el = r.one(el, "limit", what)
    if limit_el is not None:
        w = f"{what} <limit>"
        limit = Limit(r.optional(limit_el, "lower", w), r.optional(limit_el, "upper", w),
                      r.optional(limit_el, "effort", w), r.optional(limit_el, "velocity", w))
        if limit.lower is not None and limit.upper is not None and limit.lower > limit.upper:
            raise r.error(limit_el, w, f"lower={limit.lower!r} is above upper={limit.upper!r}")
    dynamics = None
    dyn_el = r.one(el, "dynamics", what)
    if dyn_el is not None:
        w = f"{what} <dynamics>"
        dynamics = Dynamics(r.number(dyn_el, "damping", w, 0.0), r.number(dyn_el, "friction", w, 0.0))
        for attr, value in (("damping", dynamics.damping), ("friction", dynamics.friction)):
            if value < 0:
                raise r.error(dyn_el, w, f"negative {attr}={value!r}")
    mimic = None
    mimic_el = r.one(el, "mimic", what)
    if mimic_el is not None:
        w = f"{what} <mimic>"
        mimic = Mimic(r.text(mimic_el, "joint", w), r.number(mimic_el, "multiplier", w, 1.0),
                      r.number(mimic_el, "offset", w, 0.0))
    return Joint(name, jtype, parent, child, xyz, rpy, axis, limit, dynamics, mimic, r.lines.get(el))


def _check_max_bytes(max_bytes, filename: str) -> int | None:
    if max_bytes is None:
        return None
    if isinstance(max_bytes, bool) or not isinstance(max_bytes, int) or max_bytes <= 0:
        raise URDFError(f"max_bytes must be a positive integer or None, got {max_bytes!r:.80}", filename, None, "")
    return max_bytes


def _too_large(filename: str, size: str, max_bytes: int) -> URDFError:
    return URDFError(f"the URDF is {size}, above the size cap of {max_bytes} bytes "
                     f"({max_bytes / 2**20:.3g} MiB); pass max_bytes= a larger number (or None) to read it",
                     filename, None, "")


def parse(text: str | bytes, *, filename: str = "<string>", max_bytes: int | None = MAX_BYTES) -> RobotDescription:
    """The checked :class:`RobotDescription` of URDF ``text`` (``filename`` names it in errors).

    ``max_bytes``: the largest text accepted, in bytes (UTF-8), default :data:`MAX_BYTES`;
    None: no cap. A larger one is a :class:`URDFError` naming the file and the cap."""
    max_bytes = _check_max_bytes(max_bytes, filename)
    if isinstance(text, str):
        text = text.encode("utf-8")
    if max_bytes is not None and len(text) > max_bytes:
        raise _too_large(filename, f"{len(text)} bytes", max_bytes)
    root, lines = _read_tree(text, filename)
    r = _Reader(filename, lines)
    if root.tag != "robot":
        raise r.error(root, f"<{root.tag}>", "the root element is not <robot>")
    name = root.get("name") or Path(filename).stem

    links: dict[str, Link] = {}
    for el in root.findall("link"):
        lname = r.text(el, "name", "<link>")
        if lname in links:
            raise r.error(el, f"link {lname!r}", f"link name {lname!r} is used twice (first on line "
                                                 f"{links[lname].line})")
        inertial_el = r.one(el, "inertial", f"link {lname!r}")
        inertial = None if inertial_el is None else _inertial(r, inertial_el, lname)
        collisions = tuple(_collision(r, c, lname) for c in el.findall("collision"))
        links[lname] = Link(lname, inertial, lines.get(el), collisions)
    if not links:
        raise r.error(root, f"robot {name!r}", "no <link> elements")

    joints: dict[str, Joint] = {}
    parent_joint: dict[str, str] = {}
    for el in root.findall("joint"):
        j = _joint(r, el)
        if j.name in joints:
            raise r.error(el, f"joint {j.name!r}", f"joint name {j.name!r} is used twice (first on line "
                                                   f"{joints[j.name].line})")
        for role, lname in (("parent", j.parent), ("child", j.child)):
            if lname not in links:
                raise r.error(el, f"joint {j.name!r} <{role}>", f"{role} link {lname!r} is not a <link> of the robot")
        if j.parent == j.child:
            raise r.error(el, f"joint {j.name!r}", f"link {j.child!r} is its own parent (a cycle)")
        if j.child in parent_joint:
            raise r.error(el, f"joint {j.name!r} <child>",
                          f"link {j.child!r} is already the child of joint {parent_joint[j.child]!r}: a link has one "
                          "parent in a tree (closed chains are not URDF)")
        joints[j.name] = j
        parent_joint[j.child] = j.name

    for j in joints.values():
        if j.mimic is not None and j.mimic.joint not in joints:
            raise r.error(None, f"joint {j.name!r} <mimic>", f"mimics joint {j.mimic.joint!r}, which does not exist")

    roots = [lname for lname in links if lname not in parent_joint]
    if len(roots) > 1:
        raise r.error(None, f"robot {name!r}", f"several root links (links that are no joint's child): "
                                               f"{', '.join(map(repr, roots))}; a URDF tree has one root")
    # Every link's parent chain must reach the root; else it runs in a circle. Each link is
    # walked up once: a walk stops at a link already known to reach the root (linear in links).
    reaches_root: set[str] = set()
    for lname in links:
        seen = [lname]
        position = {lname: 0}  # link -> its index in seen
        while seen[-1] in parent_joint and seen[-1] not in reaches_root:
            up = joints[parent_joint[seen[-1]]].parent
            if up in position:
                cycle = seen[position[up]:] + [up]
                raise r.error(None, f"joint {parent_joint[seen[-1]]!r}",
                              "the joints form a cycle through links " + " -> ".join(map(repr, reversed(cycle))))
            position[up] = len(seen)
            seen.append(up)
        reaches_root.update(seen)
    if not roots:  # unreachable: a cycle is found above
        raise r.error(None, f"robot {name!r}", "no root link")

    children: dict[str, list[str]] = {}
    for j in joints.values():
        children.setdefault(j.parent, []).append(j.name)
    order: list[str] = []  # depth first: a joint, then its child's subtree; siblings in file order
    stack = list(reversed(children.get(roots[0], [])))
    while stack:
        jname = stack.pop()
        order.append(jname)
        stack += reversed(children.get(joints[jname].child, []))
    return RobotDescription(name, links, joints, roots[0], tuple(order), filename, parent_joint)


def read(path: str | os.PathLike, *, max_bytes: int | None = MAX_BYTES) -> RobotDescription:
    """The checked :class:`RobotDescription` of the URDF file at ``path``.

    ``max_bytes``: the largest file read, in bytes, default :data:`MAX_BYTES`; None: no cap. A
    larger file is a :class:`URDFError` naming it and the cap, found from its size before it
    is read (and never more than ``max_bytes + 1`` bytes are read)."""
    return parse(read_bytes(path, max_bytes=max_bytes), filename=str(path), max_bytes=max_bytes)


def read_bytes(path: str | os.PathLike, *, max_bytes: int | None = MAX_BYTES) -> bytes:
    """The bytes of the URDF file at ``path``, at most ``max_bytes`` (see :func:`read`)."""
    path = Path(path)
    max_bytes = _check_max_bytes(max_bytes, str(path))
    try:
        return read_bounded(path, max_bytes=max_bytes)
    except FileProblem as exc:
        if exc.kind == "too large":
            raise _too_large(str(path), exc.detail, max_bytes) from None
        reason = f"cannot read the file: {exc.detail}" if exc.kind == "unreadable" else \
            f"cannot read the file: it is {exc.detail}, not a regular file"
        raise URDFError(reason, str(path), None, "") from None
