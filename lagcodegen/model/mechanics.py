"""Import models written with :mod:`sympy.physics.mechanics` as lagcodegen :class:`Model` s.

One job: sympy's mechanics objects into models, through one expression importer
(:class:`_Importer`: dynamicsymbols to the model's symbols, parameters, loads) that the Lagrangian
imports (from_lagrangian, from_bodies, from_system) and Kane's (from_kanes_method) share.

Users of sympy's mechanics package can bring their models as they are:

* :func:`from_lagrangian` takes a Lagrangian L(q(t), q'(t), t), for example built by
  ``sympy.physics.mechanics.Lagrangian(N, *bodies)`` or written by hand;
* :func:`from_bodies` takes the inertial frame and the bodies themselves, and keeps the
  kinetic and potential energies apart (so energy outputs are exact);
* :func:`from_system` takes a ``sympy.physics.mechanics.System`` built with joints
  (``PinJoint``, ``PrismaticJoint``, ``SphericalJoint``, ...), its bodies, loads and actuators:
  as a Lagrangian model when its generalized speeds are the coordinates' time derivatives
  (u = q') and it has no constraints, else through Kane's equations (:func:`from_kanes_method`);
* :func:`from_kanes_method` takes a ``KanesMethod`` on which ``kanes_equations`` has run: its
  coordinates, speeds, kinematic equations and M u' = forcing (dependent speeds' constraint rows
  included) as a model with generalized speeds and equations given directly
  (:meth:`Model.equations_of_motion`).

:func:`as_model` lets :func:`lagcodegen.derive` and :func:`lagcodegen.compile_model` take a
System or a KanesMethod.

Supported sympy.physics.mechanics objects:

* coordinates: ``dynamicsymbols`` q(t) (functions of ``dynamicsymbols._t`` or of ``time``);
  q'(t) may appear, higher derivatives may not;
* bodies: ``Particle`` and ``RigidBody`` (also the deprecated ``Body``), whose velocities
  follow from ``Point.set_vel`` / ``v2pt_theory`` / ``set_pos`` and ``ReferenceFrame``
  orientations, and whose ``potential_energy`` is set as usual;
* loads, in the ``forcelist`` format of ``LagrangesMethod``: ``(Point, Vector)`` and
  ``(ReferenceFrame, Vector)`` tuples, ``Force`` and ``Torque`` objects, and actuators
  (``ForceActuator``, ``LinearSpring``, ``TorqueActuator``, ... via ``to_loads()``). A force F
  at point P gives Q_i = F . dv_P/dq_i' (partial velocities in the inertial frame, eq. 2.6);
  a torque on frame B gives Q_i = T . dw_B/dq_i', the same as ``LagrangesMethod``;
* a Rayleigh dissipation function in q'(t) (eq. 3.15).

Not supported: constraint equations of a Lagrangian (``hol_coneqs``/``nonhol_coneqs``), a
System's or KanesMethod's holonomic constraints without dependent coordinates and speeds (sympy
cannot form Kane's equations then; lagcodegen.ConstrainedSystem takes the unconstrained model and
the constraints), and ``LagrangesMethod`` / ``JointsMethod`` objects (pass the ``System``, or the
bodies and coordinates to :func:`from_bodies`, or the Lagrangian to :func:`from_lagrangian`).

Conversion: q_i(t) becomes the plain symbol named like q_i, q_i'(t) the symbol
``<name>_dot`` (:meth:`Model.dot`), time the model's ``t``. Every other free symbol is a
parameter whose default value must be given in ``parameters`` (by symbol or name); symbols
with assumptions (``symbols('m', positive=True)``) become plain parameter symbols of the
same name. Anything left that is a function of time (a dynamicsymbol that is not a
coordinate) is an error, as is a parameter without a value.
"""

from __future__ import annotations

import warnings
from typing import Iterable, Mapping, Sequence

import sympy as sp
from sympy.core.function import AppliedUndef

from ..errors import ModelError
from ..util import excerpt
from .model import Model

#: sympy.physics.mechanics and .vector, bound by _physics() on first use: importing them is slow
#: (the package pulls in sympy's unit systems), which every other use of lagcodegen (the command
#: line, model files, lagcodegen's own models) does without.
Particle = RigidBody = dynamicsymbols = Point = ReferenceFrame = Vector = partial_velocity = ActuatorBase = None
System = KanesMethod = None


def _physics() -> None:
    """Import sympy.physics.mechanics and .vector into this module's names (once)."""
    global Particle, RigidBody, dynamicsymbols, Point, ReferenceFrame, Vector, partial_velocity, ActuatorBase
    global System, KanesMethod
    if Particle is not None:
        return
    from sympy.physics.mechanics import KanesMethod, Particle, RigidBody, dynamicsymbols
    try:  # System exists from sympy 1.13 on
        from sympy.physics.mechanics import System
    except ImportError:  # pragma: no cover - older sympy
        System = None
    from sympy.physics.vector import Point, ReferenceFrame, Vector, partial_velocity
    try:  # actuators exist from sympy 1.13 on
        from sympy.physics.mechanics.actuator import ActuatorBase
    except ImportError:  # pragma: no cover - older sympy
        ActuatorBase = None

__all__ = ["from_lagrangian", "from_bodies", "from_system", "from_kanes_method", "as_model"]

#: A value given for a parameter: by symbol or by name.
ParameterValues = Mapping[sp.Symbol | str, float]


def from_lagrangian(L, q: Sequence, *, parameters: ParameterValues | None = None, forces=None,
                    frame: ReferenceFrame | None = None, dissipation=None, name: str = "model",
                    time: sp.Symbol | None = None) -> Model:
    """A :class:`Model` from a Lagrangian in sympy.physics.mechanics form.

    Parameters
    ----------
    L:
        The Lagrangian, a sympy expression in the dynamicsymbols ``q`` (functions of time),
        their first derivatives, time and parameters, e.g. ``Lagrangian(N, P1, P2)``.
    q:
        The generalized coordinates, dynamicsymbols such as ``dynamicsymbols('theta1 theta2')``.
    parameters:
        Default value of every other free symbol of L (and of the forces and dissipation),
        keyed by symbol or name, in the order the model declares them.
    forces:
        Non-conservative loads in ``LagrangesMethod``'s ``forcelist`` format (see the module
        docstring); needs ``frame``.
    frame:
        The inertial frame, in which point velocities and angular velocities are taken.
    dissipation:
        A Rayleigh dissipation function D(q, q', t) (eq. 3.15).
    name:
        Name of the model (an identifier; it prefixes the generated C functions).
    time:
        The time symbol of the dynamicsymbols (default ``dynamicsymbols._t``).

    The Lagrangian is split as V = -L(q, 0, t) and T = L + V. For natural systems (T
    quadratic in q') these are the kinetic and potential energies, so energy outputs are
    right; terms of L linear in q' (moving frames, gyroscopic terms) end up in T. The
    equations of motion depend on L only and are exact in every case.
    """
    _physics()
    imp = _Importer(q, time=time, name=name)
    L_conv = imp.convert(L, "the Lagrangian")
    D_conv = None if dissipation is None else imp.convert(dissipation, "the dissipation function")
    Q_conv = imp.generalized_forces(forces, frame)

    exprs = [L_conv, *([] if D_conv is None else [D_conv]), *(Q for _, _, Q in Q_conv)]
    subs = imp.declare_parameters(exprs, parameters)
    T, V = _split_lagrangian(L_conv.xreplace(subs), imp.model.speeds)
    model = imp.model
    model.kinetic_energy(T, label="T (from L)")
    if V != 0:
        model.potential_energy(V, label="V (from L)")
    imp.add_loads(Q_conv, subs)
    if D_conv is not None:
        model.dissipation(D_conv.xreplace(subs), label="D")
    model.validate()
    return model


def from_bodies(frame: ReferenceFrame, bodies: Iterable, q: Sequence, *,
                parameters: ParameterValues | None = None, forces=None, dissipation=None,
                name: str = "model", time: sp.Symbol | None = None,
                origin: Point | None = None) -> Model:
    """A :class:`Model` from sympy.physics.mechanics ``Particle`` / ``RigidBody`` objects.

    T = sum of ``body.kinetic_energy(frame)`` and V = sum of ``body.potential_energy``, each
    body's terms added separately (labelled ``T[<body>]``, ``V[<body>]``), so energy outputs
    use the true kinetic and potential energies.

    Parameters
    ----------
    frame:
        The inertial frame.
    bodies:
        ``Particle`` and ``RigidBody`` objects with velocities defined in (or computable for)
        ``frame`` and ``potential_energy`` set where there is one.
    q, parameters, forces, dissipation, name, time:
        As in :func:`from_lagrangian`.
    origin:
        Optional fixed point: each body's mass centre, located relative to it and written in
        ``frame``'s axes, is declared as a model point named like the body (so the
        ``positions`` outputs ``<body>_x/_y/_z`` exist).
    """
    _physics()
    if not isinstance(frame, ReferenceFrame):
        raise ModelError(f"from_bodies: frame must be a sympy ReferenceFrame, got {frame!r}")
    bodies = list(bodies)
    if not bodies:
        raise ModelError("from_bodies: no bodies given")
    imp = _Importer(q, time=time, name=name)

    energies: list[tuple[str, sp.Expr, sp.Expr]] = []
    for body in bodies:
        if not isinstance(body, (Particle, RigidBody)):
            raise ModelError(f"from_bodies: {body!r} is not a sympy.physics.mechanics Particle or RigidBody")
        energies.append(_energies(body, frame, imp))

    positions: list[tuple[str, sp.Matrix]] = []
    if origin is not None:
        for body in bodies:
            try:
                r = body.masscenter.pos_from(origin).to_matrix(frame)
            except ValueError as exc:
                raise ModelError(f"position of body {body.name!r} from {origin.name}: {exc}") from None
            positions.append((body.name, r.applyfunc(lambda c, b=body: imp.convert(
                c, f"position of body {b.name!r}"))))

    D_conv = None if dissipation is None else imp.convert(dissipation, "the dissipation function")
    Q_conv = imp.generalized_forces(forces, frame)

    exprs = [e for _, T, V in energies for e in (T, V)]
    exprs += [c for _, r in positions for c in r]
    exprs += ([] if D_conv is None else [D_conv]) + [Q for _, _, Q in Q_conv]
    subs = imp.declare_parameters(exprs, parameters)
    model = imp.model
    _add_energies(model, energies, subs)
    return _finish(model, imp, positions, Q_conv, D_conv, subs)


def from_system(system, *, parameters: ParameterValues | None = None, dissipation=None, name: str = "model",
                unset: float | None = None) -> Model:
    """A :class:`Model` from a ``sympy.physics.mechanics.System``: Lagrangian when its speeds are q'
    and it has no constraints (below), else Kane's equations (the last paragraph).

    The system's coordinates (``system.q``) become the model's, in order; its bodies
    (``system.bodies``: ``RigidBody`` and ``Particle``) give T = sum of
    ``body.kinetic_energy(system.frame)`` and V = sum of ``body.potential_energy``, as in
    :func:`from_bodies`; each body's mass centre, seen from ``system.fixed_point`` in
    ``system.frame``'s axes, is a model point named like the body (``positions`` outputs). Its
    loads (``system.loads``, e.g. from ``apply_uniform_gravity``) and the loads of its actuators
    (``system.actuators``, ``to_loads()``) are generalized forces Q_i = F . dv_P/dq_i' (eq. 2.6)
    or T . dw_B/dq_i', except a force that is constant in ``system.frame`` (gravity): it
    becomes the potential V = -F . r_P, r_P the point's position from ``system.fixed_point``,
    so that energy outputs hold the gravitational energy too (the same generalized force).

    The speeds must be the coordinates' time derivatives: each of ``system.u`` either is a
    q_i'(t) itself (joints made with ``speeds=q.diff(t)``), or the kinematic differential
    equations ``system.kdes`` say u_j = q_i' (the joints' default u_j - q_i' = 0 of
    ``PinJoint`` and ``PrismaticJoint``). Otherwise (a ``SphericalJoint``'s angular-velocity
    speeds, any u_j = f(q, q') other than q_i'), and with constraints (holonomic, nonholonomic,
    dependent or auxiliary speeds), the model is :func:`from_kanes_method`'s of the KanesMethod
    ``System.form_eoms()`` would build (formed here without changing the System), with
    ``system.fixed_point`` as the origin of potentials and positions; ``dissipation`` is refused
    then (give damping as loads), and constraints sympy cannot form equations for (no dependent
    coordinates or speeds declared) are a ModelError saying what to declare.

    ``parameters``: the value of every other free symbol (by symbol or name; its default as a
    model parameter); ``unset``: the value given to symbols missing from ``parameters`` (None:
    they are an error). ``dissipation``: a Rayleigh function D(q, q', t) in the coordinates'
    dynamicsymbols (eq. 3.15); ``name``: the model's name.
    """
    _physics()
    if System is None or not isinstance(system, System):
        raise ModelError(f"from_system needs a sympy.physics.mechanics.System, got {type(system).__name__}")
    q = list(system.q)
    if not q:
        raise ModelError("from_system: the System has no coordinates (add joints or coordinates)")
    imp = _Importer(q, time=None, name=name)
    constrained = [(what, items) for what, items in (("holonomic constraints", system.holonomic_constraints),
                                                     ("nonholonomic constraints", system.nonholonomic_constraints),
                                                     ("dependent coordinates", system.q_dep),
                                                     ("dependent speeds", system.u_dep),
                                                     ("auxiliary speeds", system.u_aux)) if len(items)]
    try:
        speeds = None if constrained else _speeds_of(system, imp)
    except ModelError:
        speeds = None
    if speeds is None:  # u != q' or constraints: Kane's equations of the System
        if dissipation is not None:
            raise ModelError("from_system: a dissipation function needs speeds u = q' and no constraints; give the "
                             "damping as loads of the System (e.g. a LinearDamper actuator)")
        return _system_by_kane(system, constrained, parameters=parameters, name=name, unset=unset)
    imp.set_speeds(speeds)
    frame, origin = system.frame, system.fixed_point

    energies: list[tuple[str, sp.Expr, sp.Expr]] = []
    positions: list[tuple[str, sp.Matrix]] = []
    for body in system.bodies:
        energies.append(_energies(body, frame, imp))
        try:
            r = body.masscenter.pos_from(origin).to_matrix(frame)
        except ValueError:
            continue  # no position known: no point output for it
        r = r.applyfunc(lambda c, b=body: imp.convert(c, f"position of body {body.name!r}"))
        if any(c.free_symbols & set(imp.model.coords) for c in r):  # the ground needs no output
            positions.append((body.name, r))

    loads = _loads(list(system.loads) + [load for act in system.actuators for load in act.to_loads()])
    potentials: list[tuple[str, sp.Expr]] = []
    forces = []
    for location, vector in loads:
        V = _constant_force_potential(location, vector, frame, origin, imp)
        if V is None:
            forces.append((location, vector))
        else:
            potentials.append((f"V[force at {location.name}]", V))
    D_conv = None if dissipation is None else imp.convert(dissipation, "the dissipation function")
    Q_conv = imp.generalized_forces(forces, frame)

    exprs = [e for _, T, V in energies for e in (T, V)] + [V for _, V in potentials]
    exprs += [c for _, r in positions for c in r]
    exprs += ([] if D_conv is None else [D_conv]) + [Q for _, _, Q in Q_conv]
    subs = imp.declare_parameters(exprs, parameters, unset=unset)
    model = imp.model
    _add_energies(model, energies, subs)
    for label, V in potentials:
        if V != 0:
            model.potential_energy(V.xreplace(subs), label=label)
    return _finish(model, imp, positions, Q_conv, D_conv, subs)


def _system_by_kane(system, constrained: list, *, parameters, name: str, unset) -> Model:
    """The :func:`from_kanes_method` model of the KanesMethod a System's ``form_eoms`` would build
    (the same arguments, explicit kinematics), formed without changing the System; its fixed
    point is the origin of the potentials and positions."""
    loads = tuple(system.loads) + tuple(load for act in system.actuators for load in act.to_loads())
    try:
        system.validate_system(KanesMethod)
        km = KanesMethod(system.frame, q_ind=system.q_ind, u_ind=system.u_ind, kd_eqs=system.kdes,
                         q_dependent=system.q_dep, u_dependent=system.u_dep,
                         configuration_constraints=system.holonomic_constraints,
                         velocity_constraints=system.velocity_constraints, u_auxiliary=system.u_aux,
                         forcelist=loads or None, bodies=system.bodies)
        km.kanes_equations()
    except (ValueError, TypeError, AttributeError, NotImplementedError) as exc:
        reason = excerpt(" ".join(str(exc).split()), limit=100, quote=False)
        if not constrained:
            raise ModelError(f"from_system: sympy cannot form Kane's equations of the System: {reason}") from None
        (what, items), *others = constrained
        has = f"{what} ({excerpt(', '.join(map(str, items)), quote=False)})" + "".join(f", {w}" for w, _ in others)
        raise ModelError(f"from_system: the System has {has}; sympy cannot form Kane's equations of it: {reason}; "
                         "declare dependent coordinates and speeds (independent=False), or constrain the "
                         "unconstrained model in a lagcodegen.ConstrainedSystem") from None
    return from_kanes_method(km, parameters=parameters, name=name, unset=unset, origin=system.fixed_point)


def from_kanes_method(km, *, parameters: ParameterValues | None = None, name: str = "model",
                      unset: float | None = None, origin: Point | None = None) -> Model:
    """A :class:`Model` of Kane's equations formed by a ``sympy.physics.mechanics.KanesMethod``
    (``kanes_equations`` must have run), with its coordinates, speeds and parameter names.

    * coordinates: ``km.q`` (independent, then dependent ones), named like the dynamicsymbols;
    * generalized speeds: ``km.u`` (independent, then dependent ones), named like theirs, with
      the kinematic differential equations solved for q' (``km.kindiffdict()``) as the model's
      kinematics q' = k(q, u, t) (:meth:`Model.generalized_speeds`);
    * equations: ``km.mass_matrix`` u' = ``km.forcing`` given directly
      (:meth:`Model.equations_of_motion`). With dependent speeds these hold the acceleration
      constraints' rows, which make M square over all u (and not symmetric: the generated code
      solves it by LU): the same system ``km.rhs()`` integrates, so a run keeps the velocity
      constraints as well as sympy's own integration does; the configuration constraints
      (dependent coordinates) are not enforced either, as there. Auxiliary speeds are left
      out, as ``km.mass_matrix`` leaves them (zero in the kinetic energy);
    * energies, for the outputs only: T = sum of ``body.kinetic_energy(frame)`` over
      ``km.bodies`` (in q and u). The potential energy is known when every load that is a force
      constant in the inertial frame (gravity) acts at a point whose position from ``origin`` is
      known: V = -F . r_P (loads that vary are not potentials, as in :func:`from_system`);
      without ``origin`` and with such loads the potential energy, and so ``energy``, is refused
      by name. Bodies' ``potential_energy`` attributes are not used (Kane's method ignores
      them). With ``origin``, each body's mass centre seen from it is a model point
      (``positions`` outputs).

    ``origin``: a point fixed in the inertial frame (or moving only within a plane normal to
    every constant force, such as the contact point of a rolling disc on the ground).
    ``parameters``: every other free symbol's value (by symbol or name); ``unset``: the value of
    the ones missing from it (None: they are an error, naming them); ``name``: the model's.
    Dynamicsymbols other than q and u, and time derivatives of the speeds (u') are an error
    naming them.
    """
    _physics()
    if not isinstance(km, KanesMethod):
        raise ModelError(f"from_kanes_method needs a sympy.physics.mechanics.KanesMethod, got {type(km).__name__}")
    try:
        M, F = km.mass_matrix, km.forcing
    except ValueError:
        raise ModelError("from_kanes_method: Kane's equations have not been formed on this KanesMethod: call "
                         "km.kanes_equations(bodies, loads) first") from None
    q, u = list(km.q), list(km.u)
    imp = _Importer(q, time=None, name=name)
    try:
        kdd = km.kindiffdict()
    except (ValueError, AttributeError) as exc:
        raise ModelError(f"from_kanes_method: the kinematic differential equations cannot be solved for q' "
                         f"({excerpt(str(exc), quote=False)})") from None
    imp.set_generalized_speeds(u, kdd)
    kinematics = [imp.convert(kdd[sp.Derivative(f, imp.time)], f"kinematic equation of {_fname(f)!r}")
                  for f in imp.functions]
    M = M.applyfunc(lambda e: imp.convert(e, "the mass matrix of Kane's equations"))
    F = F.applyfunc(lambda e: imp.convert(e, "the forcing of Kane's equations"))
    frame = km._inertial
    aux = dict.fromkeys(getattr(km, "_uaux", None) or (), 0)  # auxiliary speeds: zero in the motion
    T = _kane_kinetic_energy(km.bodies, frame, imp, aux)
    V, why_not_V = _kane_potential(km.loads, frame, origin, imp)
    positions = _positions(km.bodies, frame, origin, imp) if origin is not None else []
    exprs = [*kinematics, *M, *F] + ([] if T is None else [T]) + ([] if V is None else [V])
    exprs += [c for _, r in positions for c in r]
    subs = imp.declare_parameters(exprs, parameters, unset=unset)
    model = imp.model
    model.generalized_speeds([_fname(w) for w in u], [k.xreplace(subs) for k in kinematics], excess=True)
    dependent = bool(getattr(km, "_udep", None))
    model.equations_of_motion(M.xreplace(subs), F.xreplace(subs),
                              kinetic_energy=None if T is None else T.xreplace(subs),
                              potential_energy=None if V is None else V.xreplace(subs),
                              symmetric=False if dependent else None, label="Kane's equations",
                              missing={"T": "a body's kinetic energy could not be formed from the KanesMethod's "
                                            "bodies" if T is None else None,
                                       "V": why_not_V})
    for body_name, r in positions:
        model.point(body_name, r.xreplace(subs))
    model.validate()
    return model


def _kane_kinetic_energy(bodies, frame, imp: "_Importer", aux: dict):
    """T = sum of the bodies' kinetic energies in ``frame``, in (q, u), the auxiliary speeds ``aux``
    set to zero; None if one cannot be formed."""
    T = sp.Integer(0)
    for body in bodies or ():
        try:
            Tb = body.kinetic_energy(frame).xreplace(aux)
        except ValueError:
            return None
        T += imp.convert(Tb, f"kinetic energy of body {body.name!r}")
    return T


def _kane_potential(loads, frame, origin, imp: "_Importer"):
    """(V, None) with V = -F . r_P summed over the forces constant in ``frame`` (gravity), r_P
    from ``origin``; (None, why) when such a force has no position from ``origin``."""
    V = sp.Integer(0)
    for location, vector in _loads(loads):
        if not isinstance(location, Point):
            continue
        try:
            Fv = vector.to_matrix(frame)
        except ValueError:
            continue
        if any(c.has(imp.time) or c.atoms(AppliedUndef) or c.atoms(sp.Derivative) for c in Fv):
            continue  # a varying force: not a potential
        if all(c == 0 for c in Fv):
            continue
        if origin is None:
            return None, (f"the constant force at point {location.name} (gravity?) has no potential without a fixed "
                          "point: import the KanesMethod with lagcodegen.model.mechanics.from_kanes_method(km, "
                          "origin=<a Point fixed in the inertial frame>)")
        Vp = _constant_force_potential(location, vector, frame, origin, imp)
        if Vp is None:
            return None, f"the position of point {location.name} from {origin.name} is not known"
        V += Vp
    return V, None


def _positions(bodies, frame, origin, imp: "_Importer") -> list:
    """(name, position of the mass centre from ``origin`` in ``frame``'s axes) of the bodies whose
    position is known and depends on the coordinates."""
    out = []
    for body in bodies or ():
        try:
            r = body.masscenter.pos_from(origin).to_matrix(frame)
        except ValueError:
            continue
        r = r.applyfunc(lambda c, b=body: imp.convert(c, f"position of body {b.name!r}"))
        if any(c.free_symbols & set(imp.model.coords) for c in r):
            out.append((body.name, r))
    return out


def as_model(obj, *, parameters: ParameterValues | None = None, unset: float | None = None):
    """``obj`` itself unless it is a ``sympy.physics.mechanics.System`` (then its
    :func:`from_system` model) or a ``KanesMethod`` on which ``kanes_equations`` has run (its
    :func:`from_kanes_method` model); ``parameters``, ``unset`` as there. Anything else is
    returned as it is (the caller checks it); other sympy.physics objects (``LagrangesMethod``,
    ...) are a ModelError saying what to pass instead.

    :func:`lagcodegen.derive` calls it with ``unset=1.0``: the derived equations are symbolic,
    the free symbols stay symbols, and their placeholder default 1.0 is announced by a
    warning; :func:`lagcodegen.compile_model` passes its ``values`` as ``parameters`` and no
    ``unset`` (a compiled model needs every value). sympy.physics.mechanics is imported only
    when ``obj`` comes from it."""
    module = type(obj).__module__ or ""
    if not module.startswith("sympy.physics"):
        return obj
    _physics()
    if System is not None and isinstance(obj, System):
        return from_system(obj, parameters=parameters, unset=unset)
    if isinstance(obj, KanesMethod):
        return from_kanes_method(obj, parameters=parameters, unset=unset)
    kind = type(obj).__name__
    hint = {"LagrangesMethod": "pass the System it came from, or its Lagrangian and coordinates to "
                               "mechanics.from_lagrangian"}.get(kind, "pass a System or a KanesMethod, or use "
                                                                      "mechanics.from_bodies / from_lagrangian")
    raise ModelError(f"a sympy.physics.mechanics {kind} is not a model lagcodegen derives: {hint}")


def _speeds_of(system, imp: "_Importer") -> dict:
    """{u_j(t): q_i'(t)} for the speeds of ``system`` that are not written as q_i'(t) themselves;
    a ModelError when a speed is not the time derivative of one coordinate."""
    t = imp.time
    qdots = [sp.Derivative(f, t) for f in imp.functions]
    u = list(system.u)
    if len(u) != len(qdots):
        raise ModelError(f"from_system: the System has {len(qdots)} coordinates but {len(u)} speeds; lagcodegen's "
                         "speeds are the coordinates' time derivatives q' (one per coordinate)")
    kdes = [k for k in system.kdes if k != 0]
    solution: dict = {}
    if kdes:
        try:
            found = sp.solve(kdes, qdots, dict=True)
        except (NotImplementedError, ValueError):
            found = []
        if len(found) != 1:
            raise ModelError(f"from_system: the kinematic differential equations {excerpt(kdes)} cannot be solved for "
                             f"{excerpt(', '.join(map(str, qdots)), quote=False)} one way; lagcodegen needs "
                             "speeds u = q'")
        solution = found[0]
    mapping = {}
    bad = []
    for qd in qdots:
        if qd in u:
            continue
        value = solution.get(qd)
        if value is None or value not in u or value in mapping:
            bad.append(f"{qd} = {value if value is not None else '(not given)'}")
            continue
        mapping[value] = qd
    if bad:
        raise ModelError("from_system: the System's speeds are not the coordinates' time derivatives (its kinematic "
                         f"differential equations give {excerpt('; '.join(bad), quote=False)}); lagcodegen's "
                         "equations (eq. 3.16) "
                         "are in q': "
                         "make each joint's speeds the time derivatives of its coordinates (e.g. "
                         "PinJoint(..., coordinates=q1, speeds=q1.diff(t)); for a SphericalJoint, speeds=[q.diff(t) "
                         "for q in its coordinates]), or keep kinematic equations u_i - q_i' = 0 (PinJoint's and "
                         "PrismaticJoint's default)")
    return mapping


def _constant_force_potential(location, vector, frame, origin, imp: "_Importer"):
    """V = -F . r for a force F constant in ``frame`` at a point whose position r from ``origin``
    is known (gravity); None for anything else (torques, forces that vary, points without a
    position)."""
    if not isinstance(location, Point):
        return None
    try:
        F = vector.to_matrix(frame)
        r = location.pos_from(origin).to_matrix(frame)
    except ValueError:
        return None
    if any(c.has(imp.time) or c.atoms(AppliedUndef) or c.atoms(sp.Derivative) for c in F):
        return None
    return imp.convert(-(F.T * r)[0], f"potential of the force at point {location.name}")


# ---------------------------------------------------------------------- helpers
def _fname(f: AppliedUndef) -> str:
    """The name of an undefined function such as the dynamicsymbol theta(t)."""
    return f.func.__name__


def _split_lagrangian(L: sp.Expr, speeds: Sequence[sp.Symbol]) -> tuple[sp.Expr, sp.Expr]:
    """(T, V) with T - V = L and V = -L(q, q' = 0, t)."""
    at_rest = dict.fromkeys(speeds, 0)
    static, moving = L.as_independent(*speeds, as_Add=True)
    if moving.subs(at_rest) == 0:  # the usual case: the terms in q' vanish at rest
        return moving, -static
    L0 = L.subs(at_rest)
    if L0.has(sp.nan, sp.zoo, sp.oo, -sp.oo):  # L singular at rest: keep it whole
        return L, sp.Integer(0)
    return L - L0, -L0


def _loads(forces) -> list[tuple[object, Vector]]:
    """Flatten a forcelist into (Point | ReferenceFrame, Vector) pairs."""
    if forces is None:
        return []
    try:
        items = list(forces)
    except TypeError:
        raise ModelError(f"forces must be a list of (Point, Vector) / (ReferenceFrame, Vector) "
                         f"pairs, got {excerpt(forces)}") from None
    out = []
    for item in items:
        if ActuatorBase is not None and isinstance(item, ActuatorBase):
            out += _loads(item.to_loads())
            continue
        if not isinstance(item, tuple) or len(item) != 2:
            raise ModelError(f"load {excerpt(item)} is not a (Point, Vector) or (ReferenceFrame, Vector) pair")
        location, vector = item
        if not isinstance(location, (Point, ReferenceFrame)):
            raise ModelError(f"load {excerpt(item)}: the location must be a Point (force) or a ReferenceFrame "
                             f"(torque); for a body use Force(body, F) or Torque(body, T)")
        if not isinstance(vector, Vector):
            if vector == 0:
                continue
            raise ModelError(f"load on {location.name}: {excerpt(vector)} is not a sympy.physics.vector Vector")
        out.append((location, vector))
    return out


def _finish(model, imp, positions, Q_conv, D_conv, subs):
    """The imported model completed: the bodies' points, the loads, the dissipation (parameters
    substituted by ``subs``), validated."""
    for body_name, r in positions:
        model.point(body_name, r.xreplace(subs))
    imp.add_loads(Q_conv, subs)
    if D_conv is not None:
        model.dissipation(D_conv.xreplace(subs), label="D")
    model.validate()
    return model


def _add_energies(model, energies, subs) -> None:
    """Each body's (name, T, V) of ``energies`` into ``model`` (parameters substituted by ``subs``)."""
    for body_name, T, V in energies:
        if T != 0:
            model.kinetic_energy(T.xreplace(subs), label=f"T[{body_name}]")
        if V != 0:
            model.potential_energy(V.xreplace(subs), label=f"V[{body_name}]")


def _energies(body, frame, imp) -> tuple[str, sp.Expr, sp.Expr]:
    """(name, T, V) of a sympy mechanics body in ``frame``, converted by ``imp`` (:class:`_Importer`)."""
    try:
        T = body.kinetic_energy(frame)
    except ValueError as exc:
        raise ModelError(f"kinetic energy of body {body.name!r} in frame {frame.name}: {exc}") from None
    T = imp.convert(T, f"kinetic energy of body {body.name!r}")
    V = imp.convert(body.potential_energy, f"potential energy of body {body.name!r}")
    return body.name, T, V


class _Importer:
    """Converts sympy.physics.mechanics expressions into the symbols of a new Model."""

    def __init__(self, q: Sequence, *, time: sp.Symbol | None, name: str):
        self.time = dynamicsymbols._t if time is None else time
        if not isinstance(self.time, sp.Symbol):
            raise ModelError(f"time must be a sympy Symbol, got {self.time!r}")
        if isinstance(q, sp.Basic) or isinstance(q, (str, bytes)):
            q = [q]
        q = list(q)
        if not q:
            raise ModelError("no generalized coordinates given")
        self.model = Model(name)
        self.functions: list[AppliedUndef] = []
        for qi in q:
            if not (isinstance(qi, AppliedUndef) and qi.args == (self.time,)):
                raise ModelError(f"coordinate {qi!r} is not a dynamicsymbol q({self.time}) "
                                 f"(make it with dynamicsymbols('{qi}'))")
            if qi in self.functions:
                raise ModelError(f"coordinate {_fname(qi)!r} is given twice")
            self.functions.append(qi)
        coords = self.model.coordinates([_fname(f) for f in self.functions])
        self.coords = dict(zip(self.functions, coords))
        self.velocities = {sp.Derivative(f, self.time): self.model.dot(c) for f, c in self.coords.items()}
        self.taken = {s.name for s in self.model.coords} | {s.name for s in self.model.speeds}
        self.speed_subs: dict = {}  # generalized speeds u_j(t) that are q_i'(t) -> q_i'(t)
        self.partial_speeds = list(self.velocities)  # the speeds of the partial velocities, by coordinate
        self.gspeeds: dict = {}  # generalized speeds u_j(t) other than q' (Kane's) -> plain symbols
        self.kin_subs: dict = {}  # q_i'(t) -> k_i(q(t), u(t), t) when there are such speeds

    def set_generalized_speeds(self, u: Sequence, kindiff: dict) -> None:
        """Take the dynamicsymbols ``u`` as generalized speeds (plain symbols named like them) and
        ``kindiff`` ({q_i'(t): k_i(q, u, t)}, every coordinate) as the kinematic equations."""
        for w in u:
            if not (isinstance(w, AppliedUndef) and w.args == (self.time,)):
                raise ModelError(f"speed {w!r} is not a dynamicsymbol u({self.time})")
            if w in self.coords:
                raise ModelError(f"{_fname(w)!r} is both a coordinate and a speed")
            if _fname(w) in self.taken:
                raise ModelError(f"speed {_fname(w)!r}: the name is taken by a coordinate or its velocity")
            self.gspeeds[w] = sp.Symbol(_fname(w))
        if len(set(self.gspeeds.values())) != len(self.gspeeds) or len(self.gspeeds) != len(u):
            raise ModelError("a speed is given twice")
        missing = [_fname(f) for f in self.functions if sp.Derivative(f, self.time) not in kindiff]
        if missing:
            raise ModelError(f"the kinematic differential equations give no q' for {', '.join(missing)}")
        self.kin_subs = {d: kindiff[d] for d in (sp.Derivative(f, self.time) for f in self.functions)}
        self.taken |= {s.name for s in self.gspeeds.values()}

    def set_speeds(self, mapping: dict) -> None:
        """Take the speeds u_j(t) of ``mapping`` ({u_j(t): q_i'(t)}) as the velocities q_i'."""
        self.speed_subs = dict(mapping)
        by_qdot = {qd: u for u, qd in mapping.items()}
        self.partial_speeds = [by_qdot.get(qd, qd) for qd in self.velocities]

    # -------------------------------------------------------------- expressions
    def convert(self, expr, what: str) -> sp.Expr:
        """Replace q(t), q'(t) and time by model symbols; reject anything else of time."""
        if isinstance(expr, Vector):
            raise ModelError(f"{what} is a Vector, expected a scalar expression")
        try:
            expr = sp.sympify(expr, strict=True)
        except (sp.SympifyError, TypeError) as exc:
            raise ModelError(f"{what} is not a sympy expression: {excerpt(expr)}") from exc
        if self.speed_subs:
            expr = expr.xreplace(self.speed_subs)
        if self.kin_subs:
            expr = expr.xreplace(self.kin_subs)
        clash = sorted(s.name for s in expr.free_symbols - {self.time} if s.name in self.taken)
        if clash:
            raise ModelError(f"{what} uses symbol(s) {', '.join(clash)} whose names are taken by the "
                             f"coordinates or their velocities")
        repl: dict = {}
        for d in expr.atoms(sp.Derivative):
            f = d.expr
            if f in self.gspeeds:
                raise ModelError(f"{what} contains the time derivative {d} of the speed {_fname(f)!r}: only the "
                                 "coordinates and speeds may appear (no accelerations)")
            if isinstance(f, AppliedUndef) and f not in self.coords:
                raise ModelError(f"{what} contains {_fname(f)!r} (as {d}), a dynamicsymbol that is not "
                                 f"a generalized coordinate")
            if f in self.coords and all(v == self.time for v in d.variables):
                order = len(d.variables)
                if order > 1:
                    raise ModelError(f"{what} contains a derivative of order {order} of {_fname(f)!r} "
                                     f"({d}); only q and q' may appear")
                repl[d] = self.velocities[d]
            else:
                raise ModelError(f"{what} contains the derivative {d}: only first time derivatives of "
                                 f"the coordinates may appear")
        repl.update(self.coords)
        repl.update(self.gspeeds)
        repl[self.time] = self.model.t
        expr = expr.xreplace(repl)
        stray = sorted(expr.atoms(AppliedUndef), key=str)
        if stray:
            listed = ", ".join(f"{_fname(f)!r} (as {f})" for f in stray)
            kind = "a generalized coordinate or speed" if self.gspeeds else "a generalized coordinate"
            raise ModelError(f"{what} contains {listed}: not {kind}; add it to q "
                             f"or substitute it")
        return expr

    def declare_parameters(self, exprs: Iterable[sp.Expr], values: ParameterValues | None,
                           unset: float | None = None) -> dict:
        """Declare every free symbol of ``exprs`` that is not q, q' or t as a parameter.

        Parameters are declared in the order of ``values`` (then the ``unset`` ones, by name).
        Returns the substitution taking the user's symbols to the model's parameter symbols.
        ``unset``: the value of symbols ``values`` misses (None: an error names them).
        """
        known = self.model.known_symbols() | set(self.gspeeds.values())
        by_name: dict[str, sp.Symbol] = {}
        for e in exprs:
            for s in sorted(e.free_symbols - known, key=lambda s: s.name):
                other = by_name.setdefault(s.name, s)
                if other != s:
                    raise ModelError(f"two different symbols are named {s.name!r} (with different "
                                     f"assumptions); use one symbol per parameter")
        given: dict[str, float] = {}
        for key, value in (values or {}).items():
            key_name = key if isinstance(key, str) else getattr(key, "name", None)
            if key_name is None:
                raise ModelError(f"parameter key {key!r} must be a Symbol or a name")
            if key_name in given:
                raise ModelError(f"parameter {key_name!r} is given twice")
            given[key_name] = value
        missing = sorted(set(by_name) - set(given))
        if missing and unset is not None:
            warnings.warn(f"parameter(s) {', '.join(missing)} have no value: their default is {unset} until one is "
                          f"given", stacklevel=4)
            given.update(dict.fromkeys(missing, unset))
            missing = []
        if missing:
            raise ModelError(f"no value given for parameter(s) {', '.join(missing)} "
                             f"(pass parameters={{{missing[0]!r}: <value>, ...}})")
        unused = [k for k in given if k not in by_name]
        if unused:
            raise ModelError(f"value given for unknown parameter(s) {', '.join(unused)}: the model "
                             f"uses {', '.join(sorted(by_name)) or 'no parameters'}")
        subs = {}
        for key_name, value in given.items():
            subs[by_name[key_name]] = self.model.parameter(key_name, value)
        return subs

    # -------------------------------------------------------------- loads
    def generalized_forces(self, forces, frame: ReferenceFrame | None) -> list[tuple[str, int, sp.Expr]]:
        """(label, coordinate index, Q_i) of every load: Q_i = F . dv/dq_i' (eq. 2.6)."""
        loads = _loads(forces)
        if not loads:
            return []
        if not isinstance(frame, ReferenceFrame):
            raise ModelError("forces need the inertial frame: pass frame=<ReferenceFrame>")
        qdots = self.partial_speeds
        out = []
        for location, vector in loads:
            if isinstance(location, Point):
                what = f"force at point {location.name}"
                get_vel = location.vel
            else:
                what = f"torque on frame {location.name}"
                get_vel = location.ang_vel_in
            try:
                partials = partial_velocity([get_vel(frame)], qdots, frame)[0]
                Qs = [vector.dot(v) for v in partials]
            except ValueError as exc:
                raise ModelError(f"{what}: {exc}") from None
            for i, (f, Qi) in enumerate(zip(self.functions, Qs)):
                Qi = self.convert(Qi, f"{what} (generalized force on {_fname(f)!r})")
                if Qi != 0:
                    out.append((f"{what} on {_fname(f)}", i, Qi))
        return out

    def add_loads(self, loads: list[tuple[str, int, sp.Expr]], subs: dict) -> None:
        for label, i, Q in loads:
            self.model.generalized_force(self.model.coords[i], Q.xreplace(subs), label=label)
