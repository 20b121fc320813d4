"""Rigid-body trees: placements, joints and links, stated the way robot descriptions state them.

A *link* is a rigid body attached to a parent link (or to the world) by a *joint*. As in URDF,
the joint frame sits at a fixed :class:`Placement` (``origin``) in the parent link's frame; the
joint then moves the link's frame relative to the joint frame (a rotation about, or a
translation along, the joint axis given in the joint frame), and the link's frame *is* the
moved joint frame. The link's inertial data are given in its own frame: mass, centre of mass
``com`` and the inertia tensor about the centre of mass (``ixx, iyy, izz, ixy, ixz, iyz``).

Joints (:class:`Joint`) and the coordinates they bring (declared on the model, named after the
joint):

* ``revolute``/``continuous``: one angle, named exactly as the joint (Pinocchio represents a
  continuous joint by the pair (cos, sin); here it is the angle itself);
* ``prismatic``: one displacement along the axis, named as the joint;
* ``fixed``: none (the link is rigidly attached: the derivation merges it into its parent);
* ``spherical`` (default ``rotation="quaternion"``, Pinocchio's ``JointModelSpherical``): a unit
  quaternion ``<name>_qx``, ``<name>_qy``, ``<name>_qz``, ``<name>_qw`` (Hamilton, scalar last)
  and three generalized speeds, the child's angular velocity in the child frame ``<name>_wx``,
  ``<name>_wy``, ``<name>_wz``; q' = 1/2 q (x) (0, w). No singular attitude;
* ``free`` (default ``rotation="quaternion"``, Pinocchio's ``JointModelFreeFlyer``): the joint
  frame's origin in the parent frame ``<name>_x``, ``<name>_y``, ``<name>_z``, then the
  quaternion; speeds: the linear velocity of the child's origin and its angular velocity, both
  in the child frame, ``<name>_vx, _vy, _vz, _wx, _wy, _wz``; (x, y, z)' = R(q) v;
* ``rotation="ZYX"`` on either: three intrinsic Z-Y-X (yaw-pitch-roll) Euler angles
  ``<name>_yaw``, ``<name>_pitch``, ``<name>_roll`` (R = Rz(yaw) Ry(pitch) Rx(roll)) whose
  velocities are their time derivatives. Singular (gimbal lock: the mass matrix loses rank) at
  pitch = +-pi/2: a body that turns through it is integrated with errors far above the tolerance.

Every other joint's velocity is its coordinate's time derivative q'. The quaternion joints give
the model generalized speeds v != q' (:attr:`Model.velocities`, :attr:`Model.kinematics`).

Nothing is derived here: the model only records the tree (:attr:`Model.links
<lagcodegen.model.model.Model>`); :mod:`lagcodegen.derivation` recognises it and evaluates
M(q) and F(q, q', t) of eq. 3.16 along the tree (composite rigid bodies and recursive
Newton-Euler). The world pose of a link (:meth:`Link.rotation`, :meth:`Link.position_of`) is
available in sympy for points, springs, dampers and forces attached to links.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import sympy as sp

from ..errors import ModelError
from ..util import excerpt

#: Numeric rotation entries this close to 0 or +-1 are taken as exactly 0 or +-1 (cos(pi/2) in
#: double precision is 6e-17): constants fold, and the change is below a rounding error.
SNAP = 1e-14


def _expr(value, what: str) -> sp.Expr:
    if isinstance(value, str):
        raise ModelError(f"{what} must be a number or a sympy expression, got the string {excerpt(value)}")
    try:
        e = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError):
        raise ModelError(f"{what} is not a number or symbolic expression: {excerpt(value)}") from None
    if not isinstance(e, sp.Expr) or e.has(sp.nan, sp.oo, -sp.oo, sp.zoo):
        raise ModelError(f"{what} is not a finite scalar: {excerpt(value)}")
    return e


def _snap(e: sp.Expr) -> sp.Expr:
    if e.is_Number and not e.is_Integer:
        x = float(e)
        for target in (0, 1, -1):
            if abs(x - target) < SNAP:
                return sp.Integer(target)
    return e


def _vector3(value, what: str) -> tuple:
    try:
        comps = list(value)
    except TypeError:
        raise ModelError(f"{what} must be 3 components, got {excerpt(value)}") from None
    if len(comps) != 3:
        raise ModelError(f"{what} must have 3 components, got {len(comps)}")
    return tuple(_expr(c, f"{what}[{i}]") for i, c in enumerate(comps))


def _rot_x(a):
    c, s = _snap(sp.cos(a)), _snap(sp.sin(a))
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rot_y(a):
    c, s = _snap(sp.cos(a)), _snap(sp.sin(a))
    return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rot_z(a):
    c, s = _snap(sp.cos(a)), _snap(sp.sin(a))
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


_AXIS_ROT = {"x": _rot_x, "y": _rot_y, "z": _rot_z}


def axis_rotation(axis: Sequence, angle) -> sp.Matrix:
    """The rotation by ``angle`` about the unit vector ``axis`` (Rodrigues' formula:
    R = cos a 1 + sin a [u]x + (1 - cos a) u u^T)."""
    u = sp.Matrix(axis)
    c, s = _snap(sp.cos(angle)), _snap(sp.sin(angle))
    ux = sp.Matrix([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return (c * sp.eye(3) + s * ux + (1 - c) * u * u.T).applyfunc(lambda e: _snap(sp.expand(e)) if e.is_number else e)


def _unit(axis, what: str) -> tuple:
    a = _vector3(axis, what)
    if all(c.is_number for c in a):
        norm = sp.sqrt(sum(c**2 for c in a))
        if norm == 0 or abs(float(norm)) < 1e-300:
            raise ModelError(f"{what} is the zero vector")
        if abs(float(norm) - 1) > 1e-12:
            a = tuple(c / norm for c in a)
        a = tuple(_snap(sp.nsimplify(c) if c.is_Float and float(c) in (0.0, 1.0, -1.0) else c) for c in a)
    return a


@dataclass(frozen=True)
class Placement:
    """A rigid placement: a rotation (3x3, the axes of the placed frame in the reference frame)
    and a translation (the placed frame's origin in the reference frame). Entries are numbers
    or sympy expressions of the model's parameters.

    ``Placement(xyz=(x, y, z), rpy=(roll, pitch, yaw))`` is URDF's ``<origin>``: R = Rz(yaw)
    Ry(pitch) Rx(roll); ``Placement(xyz=..., rotation=R)`` takes the matrix itself;
    :meth:`axis_angle` and :meth:`euler` build the rotation from an axis and angle or from an
    Euler-angle set."""

    rotation: sp.ImmutableMatrix
    translation: sp.ImmutableMatrix

    def __init__(self, xyz: Sequence = (0, 0, 0), rpy: Sequence | None = None, *, rotation=None):
        if rpy is not None and rotation is not None:
            raise ModelError("Placement: give rpy or rotation, not both")
        t = _vector3(xyz, "placement xyz")
        if rotation is not None:
            rows = rotation.tolist() if isinstance(rotation, sp.MatrixBase) else [list(r) for r in rotation]
            if len(rows) != 3 or any(len(r) != 3 for r in rows):
                raise ModelError("Placement: rotation must be a 3x3 matrix")
            R = sp.Matrix([[_snap(_expr(c, f"rotation[{i}][{j}]")) for j, c in enumerate(r)]
                           for i, r in enumerate(rows)])
            if all(c.is_number for c in R):
                err = max(abs(float(c)) for c in (R.T * R - sp.eye(3)))
                if err > 1e-9 or float(R.det()) < 0:
                    raise ModelError(f"Placement: rotation is not a proper rotation matrix (|R^T R - 1| = {err:.3g})")
        elif rpy is not None:
            r, p, y = _vector3(rpy, "placement rpy")
            R = _rot_z(y) * _rot_y(p) * _rot_x(r)
            R = R.applyfunc(lambda e: _snap(sp.expand(e)) if e.is_number else e)
        else:
            R = sp.eye(3)
        object.__setattr__(self, "rotation", sp.ImmutableMatrix(R))
        object.__setattr__(self, "translation", sp.ImmutableMatrix([_snap(c) if c.is_Float and abs(float(c)) < SNAP
                                                                     else c for c in t]))

    @classmethod
    def axis_angle(cls, axis: Sequence, angle, *, xyz: Sequence = (0, 0, 0)) -> "Placement":
        """The rotation by ``angle`` about ``axis`` (normalized), placed at ``xyz``."""
        return cls(xyz, rotation=axis_rotation(_unit(axis, "Placement axis"), _expr(angle, "Placement angle")))

    @classmethod
    def euler(cls, angles: Sequence, sequence: str = "ZYX", *, xyz: Sequence = (0, 0, 0)) -> "Placement":
        """The rotation of an Euler-angle set: ``sequence`` of three axis letters, upper case for
        intrinsic rotations (about the moving axes: "ZYX" is R = Rz(a0) Ry(a1) Rx(a2)), lower
        case for extrinsic ones (about the fixed axes: "xyz" is R = Rz(a2) Ry(a1) Rx(a0), URDF's
        roll-pitch-yaw)."""
        if (not isinstance(sequence, str) or len(sequence) != 3 or not (sequence.isupper() or sequence.islower())
                or any(ch not in "xyz" for ch in sequence.lower())
                or sequence[0].lower() == sequence[1].lower() or sequence[1].lower() == sequence[2].lower()):
            raise ModelError(f"Placement.euler: sequence must be three axis letters, all upper case (intrinsic) "
                             f"or all lower case (extrinsic), no axis twice in a row, got {sequence!r}")
        a = [_expr(x, f"Euler angle {i}") for i, x in enumerate(angles)]
        if len(a) != 3:
            raise ModelError(f"Placement.euler: three angles needed, got {len(a)}")
        mats = [_AXIS_ROT[ch.lower()](x) for ch, x in zip(sequence, a)]
        R = mats[0] * mats[1] * mats[2] if sequence.isupper() else mats[2] * mats[1] * mats[0]
        return cls(xyz, rotation=R.applyfunc(lambda e: _snap(sp.expand(e)) if e.is_number else e))

    def __mul__(self, other: "Placement") -> "Placement":
        """The composition: ``other`` given in the frame placed by ``self``."""
        if not isinstance(other, Placement):
            return NotImplemented
        R = (self.rotation * other.rotation).applyfunc(lambda e: _snap(sp.expand(e)) if e.is_number else e)
        t = self.translation + self.rotation * other.translation
        out = Placement.__new__(Placement)
        object.__setattr__(out, "rotation", sp.ImmutableMatrix(R))
        object.__setattr__(out, "translation", sp.ImmutableMatrix(t))
        return out

    def is_identity(self) -> bool:
        return self.rotation == sp.eye(3) and all(c == 0 for c in self.translation)

    def free_symbols(self) -> set:
        return set(self.rotation.free_symbols) | set(self.translation.free_symbols)


#: Joint kinds and the suffixes of the coordinates they bring ("" : the joint's name itself).
JOINT_COORDINATES = {
    "revolute": ("",),
    "continuous": ("",),
    "prismatic": ("",),
    "fixed": (),
    "spherical": ("_yaw", "_pitch", "_roll"),
    "free": ("_x", "_y", "_z", "_yaw", "_pitch", "_roll"),
    "planar": ("_x", "_y", "_theta"),
}

#: Rotations of spherical and free joints: a unit quaternion (default; generalized speeds) or
#: Z-Y-X Euler angles (their velocities q'; singular at pitch = +-pi/2).
ROTATIONS = ("quaternion", "ZYX")

#: Coordinates and generalized speeds of the quaternion joints (Pinocchio's order).
QUATERNION_COORDINATES = {"spherical": ("_qx", "_qy", "_qz", "_qw"),
                          "free": ("_x", "_y", "_z", "_qx", "_qy", "_qz", "_qw")}
QUATERNION_SPEEDS = {"spherical": ("_wx", "_wy", "_wz"), "free": ("_vx", "_vy", "_vz", "_wx", "_wy", "_wz")}


def quaternion_rotation(x, y, z, w) -> list:
    """The rotation matrix (rows) of the quaternion (x, y, z, w) normalized: exact for any nonzero
    quaternion, so that the dynamics does not depend on the drift of its norm."""
    s = 2 / (x * x + y * y + z * z + w * w)
    return [[1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
            [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
            [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)]]


def quaternion_rates(q, w) -> list:
    """q' = 1/2 q (x) (0, w) for q = (x, y, z, s) and the angular velocity w in the body frame."""
    x, y, z, s = q
    wx, wy, wz = w
    half = sp.Rational(1, 2)
    return [half * (s * wx - z * wy + y * wz), half * (z * wx + s * wy - x * wz),
            half * (-y * wx + x * wy + s * wz), -half * (x * wx + y * wy + z * wz)]


@dataclass(frozen=True)
class Joint:
    """A joint between a parent link and its child. Build with :meth:`revolute`,
    :meth:`continuous`, :meth:`prismatic`, :meth:`fixed`, :meth:`spherical`, :meth:`free`,
    :meth:`planar`."""

    kind: str
    name: str
    axis: tuple = (0, 0, 1)
    rotation: str = "quaternion"
    #: A mimic joint (URDF's <mimic>): (leader coordinate's name, multiplier, offset): no
    #: coordinate of its own, its angle or displacement multiplier * leader + offset.
    mimic: tuple = ()

    def __post_init__(self):
        if self.kind not in JOINT_COORDINATES:
            raise ModelError(f"joint kind {self.kind!r} is unknown (known: {', '.join(JOINT_COORDINATES)})")
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"joint name {self.name!r} is not a valid identifier")
        if self.rotation not in ROTATIONS:
            raise ModelError(f"joint {self.name!r}: rotation must be one of {', '.join(map(repr, ROTATIONS))}, "
                             f"got {self.rotation!r}")

    def mimicking(self, leader: str, multiplier: float = 1.0, offset: float = 0.0) -> "Joint":
        """This 1-dof joint driven by the coordinate ``leader`` (declared before it): its angle or
        displacement is ``multiplier * leader + offset`` (URDF's <mimic>, Pinocchio's mimic joint)."""
        if self.kind not in ("revolute", "continuous", "prismatic"):
            raise ModelError(f"joint {self.name!r}: only revolute, continuous and prismatic joints mimic another")
        import math
        for what, x in (("multiplier", multiplier), ("offset", offset)):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise ModelError(f"joint {self.name!r}: mimic {what} must be a finite number, got {excerpt(x)}")
        return Joint(self.kind, self.name, self.axis, self.rotation, (str(leader), float(multiplier), float(offset)))

    @property
    def quaternion(self) -> bool:
        """True for a spherical or free joint whose rotation is a quaternion (generalized speeds)."""
        return self.kind in QUATERNION_COORDINATES and self.rotation == "quaternion"

    @classmethod
    def revolute(cls, name: str, axis: Sequence = (0, 0, 1)) -> "Joint":
        """A rotation about ``axis`` (joint frame, normalized); coordinate: the angle, named ``name``."""
        return cls("revolute", name, _unit(axis, f"axis of joint {name!r}"))

    @classmethod
    def continuous(cls, name: str, axis: Sequence = (0, 0, 1)) -> "Joint":
        """A revolute joint without limits (URDF's continuous); the coordinate is the angle."""
        return cls("continuous", name, _unit(axis, f"axis of joint {name!r}"))

    @classmethod
    def prismatic(cls, name: str, axis: Sequence = (0, 0, 1)) -> "Joint":
        """A translation along ``axis`` (joint frame, normalized); coordinate: the displacement."""
        return cls("prismatic", name, _unit(axis, f"axis of joint {name!r}"))

    @classmethod
    def fixed(cls, name: str) -> "Joint":
        """A rigid attachment (no coordinate)."""
        return cls("fixed", name)

    @classmethod
    def spherical(cls, name: str, *, rotation: str = "quaternion") -> "Joint":
        """A ball joint. Default: the quaternion ``<name>_qx, _qy, _qz, _qw`` with the angular
        velocity in the child frame ``<name>_wx, _wy, _wz`` as its speeds (Pinocchio's layout; no
        singular attitude). ``rotation="ZYX"``: Z-Y-X Euler angles ``<name>_yaw, _pitch, _roll``
        (R = Rz Ry Rx) and their rates, singular at pitch = +-pi/2."""
        return cls("spherical", name, rotation=rotation)

    @classmethod
    def free(cls, name: str, *, rotation: str = "quaternion") -> "Joint":
        """Six degrees of freedom: the translation ``<name>_x, _y, _z`` of the joint frame in the
        parent frame, then the rotation as :meth:`spherical`'s. Quaternion (default): speeds
        ``<name>_vx, _vy, _vz`` (the child origin's velocity) and ``_wx, _wy, _wz``, both in the
        child frame (Pinocchio's free flyer). ``rotation="ZYX"``: Euler angles (singular at
        pitch = +-pi/2)."""
        return cls("free", name, rotation=rotation)

    @classmethod
    def planar(cls, name: str, axis: Sequence = (0, 0, 1)) -> "Joint":
        """Motion in the plane normal to ``axis`` (URDF's planar joint): translations
        ``<name>_x``, ``<name>_y`` along the plane's axes e1, e2 (for axis z: the joint frame's x
        and y; in general (e1, e2, axis) right-handed, :func:`plane_axes`), then the rotation
        ``<name>_theta`` about ``axis``. The angle is a coordinate of its own (no singularity in
        a plane); Pinocchio's planar joint carries (cos theta, sin theta) and local velocities."""
        return cls("planar", name, _unit(axis, f"axis of joint {name!r}"))

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The names of the coordinates this joint brings to the model."""
        if self.quaternion:
            return tuple(self.name + s for s in QUATERNION_COORDINATES[self.kind])
        if self.mimic:
            return ()
        return tuple(self.name + s for s in JOINT_COORDINATES[self.kind])

    @property
    def speed_names(self) -> tuple[str, ...]:
        """The names of the generalized speeds of a quaternion joint (none for the others, whose
        speeds are their coordinates' rates)."""
        return tuple(self.name + s for s in QUATERNION_SPEEDS[self.kind]) if self.quaternion else ()

    def steps(self, coords: Sequence) -> list[tuple[str, tuple, object]]:
        """The joint as elementary motions in order, (kind "R" or "P", unit axis, coordinate):
        a spherical joint is three rotations about the moving z, y, x axes, a free joint three
        translations along the joint frame's axes followed by those rotations (Euler angles).
        Quaternion joints are no such chain (:mod:`lagcodegen.model.treedynamics` moves them as a
        whole): an empty list."""
        ex, ey, ez = (1, 0, 0), (0, 1, 0), (0, 0, 1)
        if self.quaternion:
            return []
        if self.kind in ("revolute", "continuous"):
            return [("R", self.axis, coords[0])]
        if self.kind == "prismatic":
            return [("P", self.axis, coords[0])]
        if self.kind == "spherical":
            return [("R", ez, coords[0]), ("R", ey, coords[1]), ("R", ex, coords[2])]
        if self.kind == "free":
            return [("P", ex, coords[0]), ("P", ey, coords[1]), ("P", ez, coords[2]),
                    ("R", ez, coords[3]), ("R", ey, coords[4]), ("R", ex, coords[5])]
        if self.kind == "planar":
            e1, e2 = plane_axes(self.axis)
            return [("P", e1, coords[0]), ("P", e2, coords[1]), ("R", self.axis, coords[2])]
        return []


def plane_axes(axis: Sequence) -> tuple[tuple, tuple]:
    """(e1, e2) spanning the plane normal to the unit ``axis``, with (e1, e2, axis) right-handed:
    for a coordinate axis the next two in cyclic order (z: x, y; x: y, z; y: z, x), else e1 the
    coordinate axis least aligned with ``axis`` made normal to it."""
    n = [sp.nsimplify(c) if isinstance(c, (int, float)) else c for c in axis]
    units = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
    for k, u in enumerate(units):
        if list(n) == list(u):
            return units[(k + 1) % 3], units[(k + 2) % 3]
    k = min(range(3), key=lambda i: abs(float(n[i])))
    u = units[k]
    d = sum(a * b for a, b in zip(u, n))
    e1 = [a - d * b for a, b in zip(u, n)]
    norm = sp.sqrt(sum(c * c for c in e1))
    e1 = [sp.nsimplify(c / norm) for c in e1]
    e2 = [n[1] * e1[2] - n[2] * e1[1], n[2] * e1[0] - n[0] * e1[2], n[0] * e1[1] - n[1] * e1[0]]
    return tuple(e1), tuple(e2)


def _inertia(value, what: str) -> sp.ImmutableMatrix:
    if isinstance(value, sp.MatrixBase) or (hasattr(value, "__len__") and len(value) == 3
                                            and all(hasattr(r, "__len__") for r in value)):
        rows = value.tolist() if isinstance(value, sp.MatrixBase) else [list(r) for r in value]
        if len(rows) != 3 or any(len(r) != 3 for r in rows):
            raise ModelError(f"{what} must be (ixx, iyy, izz, ixy, ixz, iyz) or a symmetric 3x3 matrix")
        I = sp.Matrix([[_expr(c, f"{what}[{i}][{j}]") for j, c in enumerate(r)] for i, r in enumerate(rows)])
        if I != I.T:
            raise ModelError(f"{what} is not symmetric")
        return sp.ImmutableMatrix(I)
    try:
        comps = list(value)
    except TypeError:
        raise ModelError(f"{what} must be (ixx, iyy, izz, ixy, ixz, iyz)") from None
    if len(comps) == 3:
        comps = comps + [0, 0, 0]
    if len(comps) != 6:
        raise ModelError(f"{what} must be (ixx, iyy, izz, ixy, ixz, iyz) (or the three principal moments), "
                         f"got {len(comps)} values")
    ixx, iyy, izz, ixy, ixz, iyz = (_expr(c, f"{what}[{i}]") for i, c in enumerate(comps))
    return sp.ImmutableMatrix([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


@dataclass(eq=False)
class Link:
    """A rigid body of a tree: its joint to ``parent`` (None: the world), the joint frame's
    ``origin`` in the parent frame, its coordinates, and its inertial data in its own frame
    (``mass``, centre of mass ``com``, ``inertia`` about the centre of mass).

    :meth:`rotation`, :meth:`position` and :meth:`position_of` give its world pose in sympy
    (products of the rotations from the root: use them for points, springs and forces attached
    to links; the derivation never expands them)."""

    name: str
    parent: "Link | None"
    joint: Joint
    origin: Placement
    mass: sp.Expr
    com: tuple
    inertia: sp.ImmutableMatrix
    coordinates: tuple
    children: list = field(default_factory=list, repr=False)
    _pose: tuple | None = field(default=None, repr=False)
    speeds: tuple = ()  # a quaternion joint's generalized speeds (Joint.speed_names)
    #: (m, h = m c, I_o): the inertia about the link frame's origin when the link was given its
    #: dynamic parameters (:func:`make_link`); the tree uses it as it is (linear in them).
    origin_inertia: tuple | None = field(default=None, repr=False)

    def local_pose(self) -> tuple[sp.Matrix, sp.Matrix]:
        """(R, p): the link frame's axes and origin in the parent frame, in sympy."""
        R, p = sp.Matrix(self.origin.rotation), sp.Matrix(self.origin.translation)
        if self.joint.quaternion:
            quat = self.coordinates[-4:]
            if self.joint.kind == "free":
                p = p + R * sp.Matrix(self.coordinates[:3])
            return R * sp.Matrix(quaternion_rotation(*quat)), p
        for kind, axis, q in self.joint.steps(self.coordinates):
            if kind == "R":
                R = R * axis_rotation(axis, q)
            else:
                p = p + R * sp.Matrix(axis) * q
        return R, p

    def pose(self) -> tuple[sp.Matrix, sp.Matrix]:
        """(R, x): the link frame's axes and origin in world coordinates (forward kinematics)."""
        if self._pose is None:
            R, p = self.local_pose()
            if self.parent is not None:
                Rp, xp = self.parent.pose()
                R, p = Rp * R, xp + Rp * p
            self._pose = (R, p)
        return self._pose

    def rotation(self) -> sp.Matrix:
        """The world rotation of the link frame (its axes in world coordinates)."""
        return self.pose()[0]

    def position(self) -> sp.Matrix:
        """The world position of the link frame's origin."""
        return self.pose()[1]

    def position_of(self, xyz: Sequence) -> sp.Matrix:
        """The world position of the point with coordinates ``xyz`` in the link frame."""
        R, x = self.pose()
        return x + R * sp.Matrix(_vector3(xyz, f"point of link {self.name!r}"))

    def com_position(self) -> sp.Matrix:
        """The world position of the centre of mass."""
        return self.position_of(self.com)

    @property
    def root(self) -> "Link":
        return self if self.parent is None else self.parent.root


#: The order of a link's dynamic parameters (Pinocchio's ``Inertia.toDynamicParameters``): the
#: mass, the first moments m c, the inertia about the link frame's origin (not the centre of mass).
DYNAMIC_PARAMETERS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def dynamic_parameters_inertia(values, what: str) -> tuple:
    """(m, h, I_o) of the 10 dynamic parameters ``values`` (:data:`DYNAMIC_PARAMETERS`), checked:
    numbers or sympy expressions; I_o a symmetric sympy matrix."""
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or len(values) != 10:
        raise ModelError(f"{what} must be 10 values (m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz), got "
                         f"{excerpt(values)}")
    v = [_expr(x, f"{what}[{k}] ({DYNAMIC_PARAMETERS[k]})") for k, x in enumerate(values)]
    m, h = v[0], tuple(v[1:4])
    if m.is_number and m < 0:
        raise ModelError(f"{what}: the mass is negative ({m})")
    if m.is_number and m == 0 and any(x != 0 for x in h):
        raise ModelError(f"{what}: first moments m c without mass")
    xx, xy, yy, xz, yz, zz = v[4:]
    return m, h, sp.ImmutableMatrix([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def make_link(name: str, parent: "Link | None", joint: Joint | None, origin: Placement | None, mass, com,
              inertia, coordinates: tuple, dynamic_parameters=None) -> Link:
    """A :class:`Link` with its arguments checked (called by :meth:`Model.link`). With
    ``dynamic_parameters`` (:data:`DYNAMIC_PARAMETERS`) the mass, centre of mass h/m and inertia
    about it I_o - (|h|^2 1 - h h^T)/m are derived from them, and the tree takes (m, h, I_o)
    themselves (:attr:`Link.origin_inertia`): the equations stay linear in these parameters."""
    if dynamic_parameters is not None:
        m, h, Io = dynamic_parameters_inertia(dynamic_parameters, f"dynamic_parameters of link {name!r}")
        if m == 0:
            com, IG = (0, 0, 0), Io
        else:
            hh = sp.Matrix(h)
            com, IG = tuple(x / m for x in h), Io - ((hh.T * hh)[0, 0] * sp.eye(3) - hh * hh.T) / m
        lk = make_link(name, parent, joint, origin, m, com, sp.Matrix(IG), coordinates)
        lk.origin_inertia = (m, h, Io)
        return lk
    if joint is None:
        joint = Joint.fixed(f"{name}_joint")
    if not isinstance(joint, Joint):
        raise ModelError(f"link {name!r}: joint must be a Joint (Joint.revolute(...), ...), got {joint!r}")
    origin = Placement() if origin is None else origin
    if not isinstance(origin, Placement):
        raise ModelError(f"link {name!r}: origin must be a Placement, got {origin!r}")
    m = _expr(mass, f"mass of link {name!r}")
    if m.is_number and m < 0:
        raise ModelError(f"mass of link {name!r} is negative ({m})")
    return Link(name, parent, joint, origin, m, _vector3(com, f"com of link {name!r}"),
                _inertia(inertia, f"inertia of link {name!r}"), coordinates)
