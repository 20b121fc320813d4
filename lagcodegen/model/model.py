"""The mechanical model: coordinates, parameters, bodies, energies and forces.

One job: the :class:`Model` a user states a system in; each of its methods adds one kind of term
(coordinate, parameter, body, energy, force) with the checks of its names and expressions, and
the names already taken are kept in one place (so their checks cost no loop over the model).

A :class:`Model` holds what the user states about a system, in sympy terms:

* generalized coordinates q_i (and their velocities q_i', plain symbols named ``<q>_dot``),
* parameters with default values,
* either points/bodies whose Cartesian positions x(q, t) are given (T then follows
  from eq. 2.2 of the notes) or the kinetic energy T directly,
* potentials V(q, t) (gravity, springs, or given directly; eq. 2.7),
* Cartesian forces at points, mapped to generalized forces by eq. 2.6,
* Rayleigh dissipation D (eq. 3.15) and non-potential generalized forces Q* (eq. 3.16),
* trees of rigid links joined by joints (:meth:`Model.link`, :mod:`.bodies`), whose M and F the
  derivation evaluates along the tree.

Nothing is derived here: :mod:`lagcodegen.derivation` turns a model into equations.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import sympy as sp

from ..errors import ModelError
from .bodies import Joint, Link, Placement, make_link
from .names import DERIVED_SUFFIXES, RESERVED_NAMES, RESERVED_PREFIX  # noqa: F401 (re-exported)
from .names import as_expr as _as_expr, check_name as _check_name
from .speeds import GivenEquations, check_given, declared_speeds, given_equations, quaternion_kinematics
from ..util import excerpt
from ..util import check_finite  # noqa: F401  (re-exported: lagcodegen.model.check_finite)

_NON_FINITE = (sp.nan, sp.oo, -sp.oo, sp.zoo)


def _as_mass(value, body: str, what: str = "mass") -> sp.Expr:
    """A body's mass (or inertia) as an expression: NaN or an infinity anywhere in it is a
    ModelError naming the body; a negative number warns (a negative mass integrates, but is
    rarely meant)."""
    expr = _as_expr(value, f"{what} of {body!r}")
    if isinstance(expr, sp.Basic) and expr.has(*_NON_FINITE):
        raise ModelError(f"{what} of body {body!r} is not finite: {excerpt(expr)}")
    if what == "mass" and expr.is_number and expr.is_extended_real and expr < 0:
        warnings.warn(f"mass of body {body!r} is negative ({excerpt(expr)})", stacklevel=3)
    return expr


def _as_vector(value, what: str) -> sp.Matrix:
    """A column of 1 (a point on a line), 2 or 3 expressions."""
    if isinstance(value, sp.MatrixBase):
        comps = list(value)
    else:
        try:
            comps = list(value)
        except TypeError:
            raise ModelError(f"{what} must be a vector of 1, 2 or 3 components, got {excerpt(value)}") from None
    if len(comps) not in (1, 2, 3):
        raise ModelError(f"{what} must have 1, 2 or 3 components, got {len(comps)}")
    return sp.Matrix([_as_expr(c, f"{what}[{i}]") for i, c in enumerate(comps)])


def _as_matrix3(value, what: str, allow_diagonal: bool = False) -> sp.Matrix:
    """A 3x3 matrix of expressions (strings are refused, as everywhere in the model)."""
    rows = value.tolist() if isinstance(value, sp.MatrixBase) else value
    try:
        rows = [list(r) if not isinstance(r, (str, sp.Basic, int, float)) else r for r in rows]
    except TypeError:
        raise ModelError(f"{what} must be a 3x3 matrix") from None
    if allow_diagonal and len(rows) == 3 and all(not isinstance(r, list) for r in rows):
        return sp.diag(*[_as_expr(r, f"{what}[{i}]") for i, r in enumerate(rows)])
    if len(rows) != 3 or any(not isinstance(r, list) or len(r) != 3 for r in rows):
        raise ModelError(f"{what} must be a 3x3 matrix" + (" or 3 principal moments" if allow_diagonal else ""))
    return sp.Matrix([[_as_expr(c, f"{what}[{i}][{j}]") for j, c in enumerate(r)] for i, r in enumerate(rows)])


@dataclass(frozen=True)
class Point:
    """A named point with Cartesian position x(q, t) (2-D or 3-D)."""

    name: str
    position: sp.Matrix

    @property
    def dim(self) -> int:
        return self.position.shape[0]


@dataclass(frozen=True)
class Particle:
    """A point mass."""

    name: str
    mass: sp.Expr
    point: Point


@dataclass(frozen=True)
class PlanarBody:
    """A rigid body moving in a plane: centre of mass position, rotation angle, inertia about G."""

    name: str
    mass: sp.Expr
    inertia: sp.Expr
    point: Point
    angle: sp.Expr


@dataclass(frozen=True)
class RigidBody:
    """A 3-D rigid body: centre of mass, orientation R(q, t) (body to world), inertia about G in body axes."""

    name: str
    mass: sp.Expr
    inertia: sp.Matrix
    point: Point
    orientation: sp.Matrix


@dataclass
class Model:
    """A mechanical system stated in generalized coordinates.

    Example (simple pendulum)::

        m = Model("pendulum")
        th, = m.coordinates("theta")
        l, g, mass = m.parameters(l=1.0, g=9.81, m=1.0)
        m.particle("bob", mass, (l*sp.sin(th), -l*sp.cos(th)))
        m.gravity(g)
    """

    name: str = "model"
    t: sp.Symbol = field(default_factory=lambda: sp.Symbol("t"))
    coords: list = field(default_factory=list)
    speeds: list = field(default_factory=list)
    params: dict = field(default_factory=dict)  # Symbol -> default value (float)
    points: dict = field(default_factory=dict)  # name -> Point
    bodies: list = field(default_factory=list)
    kinetic_terms: list = field(default_factory=list)  # (label, T) given directly
    potential_terms: list = field(default_factory=list)  # (label, V)
    generalized_potential_terms: list = field(default_factory=list)  # (label, U(q, q', t))
    dissipation_terms: list = field(default_factory=list)  # (label, D)
    cartesian_forces: list = field(default_factory=list)  # (label, Point, F vector)
    generalized_forces: list = field(default_factory=list)  # (label, index, Q*)
    gravity_spec: tuple | None = None  # (g, unit "up" vector)
    outputs: dict = field(default_factory=dict)  # name -> expression (user outputs)
    inputs: list = field(default_factory=list)  # names of the parameters that are input signals u(t)
    links: list = field(default_factory=list)  # rigid links of trees (bodies.Link), parents first
    springs: list = field(default_factory=list)  # (label, Point a, Point b) of spring(): what pictures draw
    units: dict = field(default_factory=dict)  # coordinate / parameter / input name -> unit ("m", "kg")
    # Generalized speeds v != q' (quaternion joints, Kane's form): the speeds and, per coordinate,
    # q' = kinematics[i](q, v, t). Both empty: v = q' (the ``speeds``), Lagrange's equations.
    velocities: list = field(default_factory=list)
    kinematics: list = field(default_factory=list)
    # Equations of motion given directly (:meth:`equations_of_motion`, Kane's equations imported from
    # sympy): GivenEquations, added to what the derivation forms from the other elements.
    given_equations: list = field(default_factory=list)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ModelError(f"model name {self.name!r} must be an identifier")

    # ------------------------------------------------------------------ symbols
    def coordinates(self, names: str | Iterable[str]) -> tuple[sp.Symbol, ...]:
        """Declare generalized coordinates q_i (eq. 1.1); return their symbols."""
        if isinstance(names, str):
            names = names.replace(",", " ").split()
        out = []
        for name in names:
            _check_name(name, "coordinate")
            self._check_free(name)
            taken = self._taken()[1]
            for suffix in DERIVED_SUFFIXES:
                if name + suffix in taken:
                    raise ModelError(f"coordinate {name!r}: {name + suffix!r} (its "
                                     f"{'velocity' if suffix == '_dot' else 'acceleration'}) is already "
                                     "the name of a coordinate or parameter")
            q = sp.Symbol(name)
            self.coords.append(q)
            self.speeds.append(sp.Symbol(f"{name}_dot"))
            if self.velocities:  # a model with generalized speeds: this coordinate's is its rate
                self.velocities.append(self.speeds[-1])
                self.kinematics.append(self.speeds[-1])
            self._note_taken(coordinate=q)
            out.append(q)
        return tuple(out)

    def coordinate(self, name: str) -> sp.Symbol:
        """Declare one generalized coordinate and return its symbol."""
        return self.coordinates([name])[0]

    def parameters(self, **defaults: float) -> tuple[sp.Symbol, ...]:
        """Declare parameters with default values (kept adjustable or folded per scene)."""
        return tuple(self.parameter(k, v) for k, v in defaults.items())

    def parameter(self, name: str, default: float) -> sp.Symbol:
        """Declare one parameter with its default value."""
        _check_name(name, "parameter")
        self._check_free(name)
        value = check_finite(default, f"parameter {name!r}")
        sym = sp.Symbol(name)
        self.params[sym] = value
        self._note_taken(parameter=sym)
        return sym

    def _names(self) -> set[str]:
        return ({s.name for s in self.coords} | {s.name for s in self.speeds} | {s.name for s in self.params}
                | {s.name for s in self.velocities})

    def _taken_key(self) -> tuple:
        return (id(self.coords), len(self.coords), id(self.speeds), len(self.speeds), id(self.params), len(self.params),
                len(self.velocities))

    def _taken(self) -> tuple[dict, set]:
        """(derived name -> (velocity or acceleration, coordinate), :meth:`_names`): kept up to
        date by :meth:`coordinates` and :meth:`parameter` (constant time per declaration), built
        again from the lists when they were changed from outside (replaced, or grown by others)."""
        cache = self.__dict__.get("_taken_cache")
        if cache is None or cache[0] != self._taken_key():
            derived: dict = {}
            for q in self.coords:  # the velocity and acceleration symbols each coordinate brings
                for suffix, what in zip(DERIVED_SUFFIXES, ("velocity", "acceleration")):
                    derived.setdefault(q.name + suffix, (what, q.name))
            cache = (self._taken_key(), derived, self._names())
            self.__dict__["_taken_cache"] = cache
        return cache[1], cache[2]

    def _note_taken(self, *, coordinate: sp.Symbol | None = None, parameter: sp.Symbol | None = None) -> None:
        """Add the names of a coordinate just appended (with its speed) or of a parameter just set
        to the cache of :meth:`_taken`, if it was up to date before; else drop it."""
        cache = self.__dict__.pop("_taken_cache", None)
        if cache is None:
            return
        key, derived, names = cache
        grown = 1 if coordinate is not None else 0
        before = (key[0], key[1] + grown, key[2], key[3] + grown, key[4], key[5] + (parameter is not None),
                  key[6] + (grown if self.velocities else 0))
        if before != self._taken_key():
            return
        if coordinate is not None:
            for suffix, what in zip(DERIVED_SUFFIXES, ("velocity", "acceleration")):
                derived.setdefault(coordinate.name + suffix, (what, coordinate.name))
            names.update((coordinate.name, self.speeds[-1].name))
        if parameter is not None:
            names.add(parameter.name)
        self.__dict__["_taken_cache"] = (self._taken_key(), derived, names)

    def _check_free(self, name: str) -> None:
        """ModelError if ``name`` is a coordinate's, speed's or parameter's, or the velocity or
        acceleration of a coordinate (constant time: :meth:`_taken`)."""
        derived, names = self._taken()
        if name in derived:
            what, q = derived[name]
            raise ModelError(f"name {name!r} is taken by the {what} of coordinate {q!r}")
        if name in names:
            raise ModelError(f"name {name!r} is declared twice")

    def dot(self, q: sp.Symbol) -> sp.Symbol:
        """The generalized velocity q' of coordinate q (eq. 2.1)."""
        return self.speeds[self.index(q)]

    def index(self, q) -> int:
        """Index of a coordinate given by symbol or name."""
        name = q if isinstance(q, str) else getattr(q, "name", None)
        # name -> index, extended as coordinates are appended (constant time per call); a hit is
        # checked against the list, which others may have changed, and a miss looked for in it.
        cached = self.__dict__.get("_index_cache")
        if cached is None or cached[0] != id(self.coords) or cached[1] > len(self.coords):
            cached = (id(self.coords), 0, {})
        positions = cached[2]
        for i in range(cached[1], len(self.coords)):
            positions.setdefault(self.coords[i].name, i)
        self.__dict__["_index_cache"] = (id(self.coords), len(self.coords), positions)
        i = positions.get(name)
        if i is not None and self.coords[i].name == name:
            return i
        for i, c in enumerate(self.coords):
            if c.name == name:
                return i
        raise ModelError(f"{q!r} is not a coordinate of model {self.name!r}")

    @property
    def n(self) -> int:
        """Number of generalized coordinates."""
        return len(self.coords)

    # ------------------------------------------------------------------ generalized speeds
    @property
    def general(self) -> bool:
        """True if the model's speeds are not its coordinates' rates (q' = G(q, t) v + g(q, t))."""
        return bool(self.velocities)

    @property
    def v(self) -> list:
        """The generalized speeds: :attr:`velocities`, or the coordinates' rates (``speeds``)."""
        return self.velocities if self.velocities else self.speeds

    @property
    def qdot(self) -> list:
        """q' per coordinate in (q, v, t): :attr:`kinematics`, or the speeds themselves."""
        return self.kinematics if self.kinematics else self.speeds

    @property
    def nq(self) -> int:
        """Number of coordinates (= :attr:`n`)."""
        return len(self.coords)

    @property
    def nv(self) -> int:
        """Number of generalized speeds (nv <= nq but for Kane's equations with ignorable coordinates left out)."""
        return len(self.v)

    def generalized_speeds(self, names: Sequence[str], kinematics, *, excess: bool = False) -> tuple[sp.Symbol, ...]:
        """Declare generalized speeds ``names`` and the kinematic equations q' = f(q, v, t) of
        every coordinate (``kinematics``: a mapping coordinate (symbol or name) -> expression, or
        a sequence in coordinate order), replacing the speeds q' the coordinates brought (Kane's
        form; notes eq. 2.1 with q' a function of the speeds). Return the speeds' symbols.

        ``excess``: allow more speeds than coordinates (Kane's equations whose ignorable
        coordinates were left out, e.g. a bicycle's wheel angles with their rates kept as speeds);
        their equations must be given directly (:meth:`equations_of_motion`): Lagrange's, projected
        onto more speeds than coordinates, would have a singular mass matrix."""
        syms, exprs = declared_speeds(self, names, kinematics, excess)
        self.velocities[:] = syms
        self.kinematics[:] = exprs
        self.__dict__.pop("_taken_cache", None)
        return tuple(syms)

    def neutral(self) -> list[float]:
        """The neutral configuration (Pinocchio's ``neutral``): every coordinate 0 but the scalar
        part of each quaternion, 1 (the identity rotation)."""
        out = [0.0] * self.n
        for lk in self.links:
            if lk.joint.quaternion:
                out[self.index(lk.coordinates[-1])] = 1.0
        return out

    def _quaternion_joint(self, joint: Joint, coords: tuple) -> tuple:
        """The generalized speeds and kinematics of a quaternion joint whose coordinates were
        just declared (:meth:`link`); returns the speeds."""
        if not self.velocities:
            self.velocities[:] = list(self.speeds)
            self.kinematics[:] = list(self.speeds)
        k = len(coords)
        del self.velocities[-k:]
        del self.kinematics[-k:]
        w, qdot = quaternion_kinematics(joint, coords)
        self.velocities.extend(w)
        self.kinematics.extend(qdot)
        self.__dict__.pop("_taken_cache", None)
        return tuple(w)

    def time_derivative(self, expr) -> sp.Expr:
        """d/dt of an expression in (q, t): sum_i dx/dq_i q_i' + dx/dt."""
        expr = sp.sympify(expr)
        return sum((sp.diff(expr, q) * v for q, v in zip(self.coords, self.speeds)),
                   sp.diff(expr, self.t))

    # ------------------------------------------------------------------ bodies
    def point(self, name: str, position) -> Point:
        """Declare a named point with position x(q, t); used by forces, springs, outputs."""
        _check_name(name, "point")
        if name in self.points:
            raise ModelError(f"point {name!r} is declared twice")
        pt = Point(name, _as_vector(position, f"position of point {name!r}"))
        self.points[name] = pt
        return pt

    def _resolve_point(self, p, what: str) -> Point:
        if isinstance(p, Point):
            return p
        if isinstance(p, str):
            if p not in self.points:
                raise ModelError(f"{what}: no point named {p!r}")
            return self.points[p]
        return Point(f"<{what}>", _as_vector(p, what))

    def particle(self, name: str, mass, position) -> Particle:
        """A point mass at x(q, t); contributes m/2 |x'|^2 to T (eq. 2.2). ``position`` has 2 or
        3 components, or 1 for a particle on a line (T = m/2 x'^2; gravity then needs an
        explicit one-component ``up``, see :meth:`gravity`)."""
        mass = _as_mass(mass, name)
        body = Particle(name, mass, self.point(name, position))
        self.bodies.append(body)
        return body

    def planar_body(self, name: str, mass, inertia, position, angle) -> PlanarBody:
        """A planar rigid body: T = m/2 |x_G'|^2 + I_G/2 angle'^2."""
        mass, inertia = _as_mass(mass, name), _as_mass(inertia, name, "inertia")
        pt = self.point(name, position)
        if pt.dim != 2:
            raise ModelError(f"planar body {name!r} needs a 2-D position")
        body = PlanarBody(name, mass, inertia, pt, _as_expr(angle, f"angle of {name!r}"))
        self.bodies.append(body)
        return body

    def rigid_body(self, name: str, mass, inertia, position, orientation) -> RigidBody:
        """A 3-D rigid body.

        ``orientation`` is the rotation matrix R(q, t) taking body axes to world axes;
        ``inertia`` the inertia tensor about the centre of mass in body axes (3x3, or the
        three principal moments). T = m/2 |x_G'|^2 + 1/2 w^T I w with [w]x = R^T R'.
        """
        mass = _as_mass(mass, name)
        inertia = _as_matrix3(inertia, f"inertia of {name!r}", allow_diagonal=True)
        if inertia.has(*_NON_FINITE):
            raise ModelError(f"inertia of body {name!r} is not finite: {inertia.tolist()}")
        pt = self.point(name, position)
        if pt.dim != 3:
            raise ModelError(f"rigid body {name!r} needs a 3-D position")
        R = _as_matrix3(orientation, f"orientation of {name!r}")
        body = RigidBody(name, mass, inertia, pt, R)
        self.bodies.append(body)
        return body

    # ------------------------------------------------------------------ trees of links
    def link(self, name: str, *, parent: "str | Link | None" = None, joint: Joint | None = None,
             origin: Placement | None = None, mass=0, com: Sequence = (0, 0, 0),
             inertia: Sequence = (0, 0, 0, 0, 0, 0), dynamic_parameters: Sequence | None = None) -> Link:
        """A rigid link of a tree (:mod:`lagcodegen.model.bodies`), attached to ``parent`` (a link
        or its name; None: the world) by ``joint`` (default: fixed) whose frame sits at ``origin``
        in the parent's frame (URDF's joint origin). ``mass``, ``com`` and ``inertia`` (ixx, iyy,
        izz, ixy, ixz, iyz about the centre of mass, in the link frame) as URDF's inertial.

        The joint's coordinates are declared here, named after the joint (a 1-dof joint: its
        name; spherical/free: :data:`~lagcodegen.model.bodies.JOINT_COORDINATES` suffixes).
        ``dynamic_parameters``, instead of those three: the 10 values (m, m c_x, m c_y, m c_z,
        Ixx, Ixy, Iyy, Ixz, Iyz, Izz) with the inertia about the link frame's origin (Pinocchio's
        ``Inertia.toDynamicParameters`` order), typically parameters: the equations of motion are
        linear in them (:func:`lagcodegen.modelfile.urdf.load`'s ``inertial_parameters``).
        Gravity (:meth:`gravity`) acts on links too. The kinetic energy of the links is
        T = 1/2 q'^T M(q) q' with M evaluated along the tree by the derivation.
        """
        _check_name(name, "link")
        if any(lk.name == name for lk in self.links) or name in self.points:
            raise ModelError(f"link {name!r} is declared twice (or is a point's name)")
        if isinstance(parent, str):
            found = [lk for lk in self.links if lk.name == parent]
            if not found:
                raise ModelError(f"link {name!r}: no parent link named {parent!r} (declare parents first)")
            parent = found[0]
        elif parent is not None and (not isinstance(parent, Link) or parent not in self.links):
            raise ModelError(f"link {name!r}: parent must be the name of a link of this model or None, got {parent!r}")
        if joint is not None and isinstance(joint, Joint):
            if any(lk.joint.name == joint.name for lk in self.links):
                raise ModelError(f"link {name!r}: joint name {joint.name!r} is used twice")
            for cname in joint.coordinate_names + joint.speed_names:
                _check_name(cname, "coordinate")
                self._check_free(cname)
        if dynamic_parameters is not None and not (isinstance(mass, (int, float)) and mass == 0
                                                   and tuple(com) == (0, 0, 0) and tuple(inertia) == (0,) * 6):
            raise ModelError(f"link {name!r}: give mass, com and inertia or dynamic_parameters, not both")
        lk = make_link(name, parent, joint, origin, mass, com, inertia, (), dynamic_parameters)
        for what, e in ([("origin", e) for e in lk.origin.free_symbols()] + [("mass", lk.mass)]
                        + [("com", c) for c in lk.com] + [("inertia", c) for c in lk.inertia]):
            bad = sp.sympify(e).free_symbols - set(self.params)
            if bad:
                raise ModelError(f"{what} of link {name!r} uses symbols that are not parameters: "
                                 f"{', '.join(sorted(s.name for s in bad))}")
        coords = self.coordinates(list(lk.joint.coordinate_names)) if lk.joint.coordinate_names else ()
        lk.coordinates = tuple(coords)
        if lk.joint.mimic:  # driven by a coordinate declared before: its angle m q + o
            leader, gain, offset = lk.joint.mimic
            if leader not in {q.name for q in self.coords}:
                raise ModelError(f"link {name!r}: joint {lk.joint.name!r} mimics {leader!r}, which is no coordinate "
                                 "declared before it")
            q = self.coords[self.index(leader)]
            lk.coordinates = (sp.Float(gain) * q + sp.Float(offset),)
        if lk.joint.quaternion:
            lk.speeds = self._quaternion_joint(lk.joint, lk.coordinates)
        if parent is not None:
            parent.children.append(lk)
        self.links.append(lk)
        return lk

    def point_on(self, link: "str | Link", xyz: Sequence, name: str) -> Point:
        """A named point fixed in ``link`` at ``xyz`` (link frame): its world position
        (:meth:`Link.position_of`) serves springs, dampers, forces, particles and outputs."""
        if isinstance(link, str):
            found = [lk for lk in self.links if lk.name == link]
            if not found:
                raise ModelError(f"point_on: no link named {link!r}")
            link = found[0]
        if not isinstance(link, Link) or link not in self.links:
            raise ModelError(f"point_on: {link!r} is not a link of this model")
        return self.point(name, link.position_of(xyz))

    # ------------------------------------------------------------------ energies
    def kinetic_energy(self, T, label: str = "T") -> None:
        """Add kinetic energy given directly in (q, q', t)."""
        self.kinetic_terms.append((label, _as_expr(T, f"kinetic energy {label!r}")))

    def potential_energy(self, V, label: str = "V") -> None:
        """Add a potential V(q, t) (eq. 2.7)."""
        self.potential_terms.append((label, _as_expr(V, f"potential {label!r}")))

    def generalized_potential(self, U, label: str = "U") -> None:
        """Add a velocity-dependent (generalized) potential U(q, q', t) (eq. 3.4).

        It enters L = T - U; its generalized force is Q_i = d/dt(dU/dq_i') - dU/dq_i.
        Example: a charge e in fields phi, A: U = e (phi - v . A).
        """
        self.generalized_potential_terms.append((label, _as_expr(U, f"generalized potential {label!r}")))

    def gravity(self, g, up: Sequence | None = None) -> None:
        """Uniform gravity on every massive body: V = sum m g (x . up).

        ``up`` defaults to the last axis (y in 2-D, z in 3-D); it is normalized. A particle on a
        line (a one-component position) has no default up: give ``up=(1,)`` for a vertical line
        pointing up (``(-1,)`` pointing down), or give the particle 2 components, e.g. ``(x, 0)``
        for a horizontal line.
        """
        if up is not None:
            up = _as_vector(up, "gravity up")
            norm = sp.sqrt(sum(c**2 for c in up))
            if norm == 0:
                raise ModelError("gravity 'up' vector is zero")
            up = up / norm
        self.gravity_spec = (_as_expr(g, "gravity"), up)

    def spring(self, a, b, k, rest_length=0, label: str | None = None) -> None:
        """A linear spring between points a and b: V = k/2 (|x_a - x_b| - L0)^2."""
        pa, pb = self._resolve_point(a, "spring end a"), self._resolve_point(b, "spring end b")
        if pa.dim != pb.dim:
            raise ModelError("spring ends have different dimensions")
        d = pa.position - pb.position
        k = _as_expr(k, "spring stiffness")
        L0 = _as_expr(rest_length, "spring rest length")
        sq = (d.T * d)[0]
        V = k / 2 * sq if L0 == 0 else k / 2 * (sp.sqrt(sq) - L0) ** 2
        self.potential_terms.append((label or f"spring {pa.name}-{pb.name}", V))
        self.springs.append((label or f"spring {pa.name}-{pb.name}", pa, pb))

    def force(self, point, vector, label: str | None = None) -> None:
        """A Cartesian force F(q, q', t) applied at a point; mapped by eq. 2.6."""
        pt = self._resolve_point(point, "force point")
        F = _as_vector(vector, f"force at {pt.name!r}")
        if F.shape != pt.position.shape:
            raise ModelError(f"force at {pt.name!r} has {F.shape[0]} components, point has {pt.dim}")
        self.cartesian_forces.append((label or f"force at {pt.name}", pt, F))

    def generalized_force(self, coordinate, expr, label: str | None = None) -> None:
        """A non-potential generalized force Q*_i(q, q', t) on one coordinate (eq. 3.16)."""
        i = self.index(coordinate)
        self.generalized_forces.append(
            (label or f"Q*[{self.coords[i].name}]", i, _as_expr(expr, f"generalized force on {self.coords[i].name!r}")))

    def equations_of_motion(self, M, F, *, kinetic_energy=None, potential_energy=None, symmetric: bool | None = None,
                            label: str = "equations", missing: dict | None = None) -> GivenEquations:
        """Add equations of motion given directly: M(q, v, t) v' = F(q, v, t), M nv x nv and F of nv
        rows in the model's coordinates, speeds :attr:`v` (the coordinates' rates q' unless
        :meth:`generalized_speeds` declared others), parameters and t. They are added to the
        equations the derivation forms from the model's other elements (bodies, energies, forces,
        links; a model may have none: Kane's equations imported from sympy,
        :func:`lagcodegen.model.mechanics.from_kanes_method`), and are not differentiated.

        ``kinetic_energy`` T(q, v, t) and ``potential_energy`` V(q, t): the energies of the system
        these equations describe, for the outputs ``energy``, ``kinetic_energy``,
        ``potential_energy`` and the momenta dT/dv only; without them those outputs are refused by
        name (as are ``dissipation``, ``jacobi_h`` and ``dh_dt``, which equations given directly do
        not determine). ``symmetric``: whether M is symmetric (None: proved by expanding M_ij - M_ji
        for small entries, else taken as not). A symmetric M is factored by Cholesky, another by LU
        with partial pivoting (Kane's equations with dependent speeds: the velocity constraints'
        rows make M square and not symmetric). ``missing``: {"T" or "V": why that energy is not
        given}, told when an output needs it."""
        eq = given_equations(self, M, F, (kinetic_energy, potential_energy), symmetric, label, missing)
        self.given_equations.append(eq)
        return eq

    def dissipation(self, D, label: str = "D") -> None:
        """Add a Rayleigh dissipation function D(q, q', t) in generalized velocities (eq. 3.15)."""
        self.dissipation_terms.append((label, _as_expr(D, f"dissipation {label!r}")))

    def damper(self, a, c, b=None, label: str | None = None) -> None:
        """A linear viscous damper on a point's velocity (or relative to point b): D = c/2 |v_a - v_b|^2."""
        pa = self._resolve_point(a, "damper point")
        v = pa.position.applyfunc(self.time_derivative)
        if b is not None:
            pb = self._resolve_point(b, "damper point b")
            v = v - pb.position.applyfunc(self.time_derivative)
        c = _as_expr(c, "damping coefficient")
        self.dissipation_terms.append((label or f"damper {pa.name}", c / 2 * (v.T * v)[0]))

    def output(self, name: str, expr) -> None:
        """A named output expression in (q, q', t), emitted when a scene asks for it."""
        _check_name(name, "output")
        self.outputs[name] = _as_expr(expr, f"output {name!r}")

    def input(self, name: str, default: float = 0.0) -> sp.Symbol:
        """Declare an input signal u(t) with its default value; return its symbol.

        An input enters T, V, forces, generalized forces, dissipation and outputs as a parameter
        does, and stays a run-time parameter of every scene (an entry of ``p``, listed in
        ``GeneratedCode.input_names``): an FMU importer sets it between steps, ``simulate(...,
        params={name: value})`` holds it constant. The derivation treats it as piecewise constant
        (as a zero-order hold between communication points): terms in du/dt, which a T or a
        damper depending on u would bring through d/dt dL/dq' (eq. 3.3), are not formed; give
        such a rate as an input of its own.
        """
        _check_name(name, "input")
        sym = self.parameter(name, check_finite(default, f"input {name!r}"))
        self.inputs.append(name)
        return sym

    def unit(self, name: str, unit: str) -> None:
        """State the unit of the coordinate, parameter or input ``name`` (a string such as "m",
        "rad", "kg", "N"). It is documentation, not checked: FMUs (lagcodegen.export_fmu) carry
        it in their modelDescription, the velocity q' and the derivatives in "<unit>/s" and
        "<unit>/s2"."""
        names = {q.name for q in self.coords} | {s.name for s in self.params}
        if name not in names:
            raise ModelError(f"unit for {name!r}: not a coordinate, parameter or input of model {self.name!r}")
        if not isinstance(unit, str) or not unit or any(c.isspace() or c in "\"'<>&" for c in unit):
            raise ModelError(f"unit of {name!r} must be a non-empty string without spaces, quotes or <>&, "
                             f"got {unit!r}")
        self.units[name] = unit

    # ------------------------------------------------------------------ checks
    def known_symbols(self) -> set:
        return set(self.coords) | set(self.speeds) | set(self.params) | {self.t} | set(self.velocities)

    def check_symbols(self, expr, what: str, allow_speeds: bool = True) -> None:
        """Raise ModelError if ``expr`` uses a symbol the model does not declare."""
        expr = sp.sympify(expr)
        allowed = self.known_symbols()
        speeds = {s.name for s in self.speeds} | {s.name for s in self.velocities}
        if not allow_speeds:
            allowed -= set(self.speeds) | set(self.velocities)
        bad = expr.free_symbols - allowed
        velocities = sorted(s.name for s in bad if s.name in speeds and not allow_speeds)
        if velocities:
            raise ModelError(f"{what} uses velocity not allowed here: {', '.join(velocities)}")
        if bad:
            names = {s.name for s in self.known_symbols()}
            msgs = []
            for s in sorted(bad, key=lambda s: s.name):
                if s.name in names:  # same name, other assumptions (e.g. Symbol('m', positive=True))
                    msgs.append(f"{s.name} (a symbol with assumptions {s.assumptions0}; use the plain "
                                f"symbol returned by Model.parameters/coordinates)")
                else:
                    msgs.append(s.name)
            raise ModelError(f"{what} uses unknown symbol(s): {', '.join(msgs)}")
        funcs = expr.atoms(sp.core.function.AppliedUndef)
        if funcs:
            raise ModelError(f"{what} uses undefined function(s): {', '.join(sorted(map(str, funcs)))}")

    def validate(self) -> None:
        """Check every expression uses declared symbols only; called by the derivation."""
        if not self.coords:
            raise ModelError(f"model {self.name!r} has no coordinates")
        for pt in self.points.values():
            self.check_symbols(pt.position, f"position of point {pt.name!r}", allow_speeds=False)
        for body in self.bodies:
            self.check_symbols(body.mass, f"mass of {body.name!r}", allow_speeds=False)
            syms = body.mass.free_symbols
            if syms and syms <= set(self.params):  # a literal negative mass warned when declared
                value = body.mass.subs(self.params)
                if value.is_number and value.is_extended_real and value < 0:
                    warnings.warn(f"mass of body {body.name!r} is negative ({excerpt(body.mass)} = "
                                  f"{excerpt(value)} with the "
                                  "parameters' default values)", stacklevel=3)
            if isinstance(body, PlanarBody):
                self.check_symbols(body.inertia, f"inertia of {body.name!r}", allow_speeds=False)
                self.check_symbols(body.angle, f"angle of {body.name!r}", allow_speeds=False)
            if isinstance(body, RigidBody):
                self.check_symbols(body.inertia, f"inertia of {body.name!r}", allow_speeds=False)
                self.check_symbols(body.orientation, f"orientation of {body.name!r}", allow_speeds=False)
        for label, T in self.kinetic_terms:
            self.check_symbols(T, f"kinetic energy {label!r}")
        for label, V in self.potential_terms:
            self.check_symbols(V, f"potential {label!r}", allow_speeds=False)
        for label, U in self.generalized_potential_terms:
            self.check_symbols(U, f"generalized potential {label!r}")
        for label, D in self.dissipation_terms:
            self.check_symbols(D, f"dissipation {label!r}")
        for label, _, F in self.cartesian_forces:
            self.check_symbols(F, label)
        for label, _, Q in self.generalized_forces:
            self.check_symbols(Q, label)
        if self.gravity_spec is not None:
            self.check_symbols(self.gravity_spec[0], "gravity", allow_speeds=False)
            if self.gravity_spec[1] is not None:
                self.check_symbols(self.gravity_spec[1], "gravity 'up' vector", allow_speeds=False)
            if not self.bodies and not self.links:
                raise ModelError("gravity() acts on the model's bodies, but it has none (T was given "
                                 "directly): add the gravitational potential with potential_energy()")
            for body in self.bodies:
                up = self.gravity_spec[1]
                dim = body.point.dim
                if up is None and dim == 1:
                    raise ModelError(f"gravity on {body.name!r}, a particle on a line (1-D position): its direction "
                                     "along the line is not defined; give gravity an up vector of one component "
                                     "(up = [1] for a vertical line pointing up, [-1] pointing down), or give "
                                     f"{body.name!r} 2 components (e.g. [x, 0] for a horizontal line)")
                if up is not None and len(up) != dim:
                    raise ModelError(f"gravity 'up' has {len(up)} components, {body.name!r} has {dim}")
        for name, expr in self.outputs.items():
            self.check_symbols(expr, f"output {name!r}")
        for eq in self.given_equations:
            check_given(self, eq.M, f"mass matrix of {eq.label!r}")
            check_given(self, eq.F, f"forces of {eq.label!r}")
            if eq.kinetic_energy is not None:
                check_given(self, eq.kinetic_energy, f"kinetic energy of {eq.label!r}")
            if eq.potential_energy is not None:
                self.check_symbols(eq.potential_energy, f"potential energy of {eq.label!r}", allow_speeds=False)
            if eq.M.shape != (self.nv, self.nv):
                raise ModelError(f"mass matrix of {eq.label!r} is {eq.M.shape[0]} x {eq.M.shape[1]}, the model has "
                                 f"{self.nv} speeds")
        if not self.bodies and not self.kinetic_terms and not self.links and not self.given_equations:
            raise ModelError(f"model {self.name!r} has no kinetic energy: add bodies or kinetic_energy()")

    # ------------------------------------------------------------------ notebooks
    def _repr_html_(self) -> str:
        """Name, coordinates, parameters, bodies, energies, forces and outputs (bounded size)."""
        from ..notebook import model_html
        return model_html(self)

    def _repr_latex_(self) -> str:
        """The coordinates and the energies stated directly, velocities dotted."""
        from ..notebook import model_latex
        return model_latex(self)


def require_model(obj, what: str) -> Model:
    """``obj`` if it is a :class:`Model`; else a ModelError saying what ``what`` (the function,
    e.g. ``"compile_model"``) takes, and what to call for what was given (a model file's path,
    a loaded model file, a constrained system)."""
    if isinstance(obj, Model):
        return obj
    takes = f"{what} takes a Model (or a sympy.physics.mechanics System or KanesMethod)"
    kind = type(obj).__name__
    if isinstance(obj, (str, bytes)) or hasattr(obj, "__fspath__"):
        hint = ("for a model file, lagcodegen.compile_file(path) compiles it with its [simulation] settings, "
                "lagcodegen.modelfile.load_model_path(path) loads it (its .model is the Model)")
        raise ModelError(f"{takes}, got the {kind} {excerpt(obj if isinstance(obj, str) else str(obj))}: {hint}")
    hints = {"ModelFile": "a loaded model file: lagcodegen.compile_file(mf) compiles it, mf.model is its Model",
             "ConstrainedSystem": "a constrained system: lagcodegen.compile_constrained(system) compiles it, "
                                  "system.model is its unconstrained Model",
             "EquationsOfMotion": "derived equations: eom.model is their Model"}
    raise ModelError(f"{takes}, got {'None' if obj is None else f'a {kind}'}"
                     + (f" ({hints[kind]})" if kind in hints else ""))
