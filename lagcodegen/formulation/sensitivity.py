"""The kernels of the forward sensitivity equations of M(q, p) q'' = F(q, q', t, p) (eq. 3.16).

For a run-time parameter p_k or an initial value, with s = dq/d(theta) and its rate s', the
tangent of the residual r(q, q', a, t, p) = M a - F (a = q'') gives

    M s'' = -(dr/dq) s - (dr/dq') s' - dr/dp_k,    dr/dy = dM a - dF,

the term dr/dp_k only for a parameter (an initial value has s(0) a unit vector and no forcing).
M is never inverted symbolically: the generated code solves with the factorization of M that
already gives q''. The quadrature rates z' = rate(q, q', t, p) give dz'/d(theta) = (drate/dy) s
+ drate/dp_k. Outputs: d out/d(theta) = (d out/dy) s + d out/dp_k.

Kernels (language-neutral :class:`~lagcodegen.formulation.kernels.Block` s, symbols ``y[i]``,
``p[k]``, ``t``, ``a[i]``):

* ``rhs``: M's upper triangle ("M", i, j), F ("F", i), the quadrature rates ("ydot", 2n + k) --
  the right-hand side kernel of :func:`~lagcodegen.formulation.kernels.model_blocks`;
* ``tangent``: ("G", i, j) = dr_i/dy_j (j < 2n), ("P", k, i) = dr_i/dp_k, ("Z", k, j) =
  drate_k/dy_j, ("Zp", k, m) = drate_k/dp_m (after the accelerations a are known);
* ``out``: ("Oy", k, i) = d out_k/dy_i, ("Op", k, m) = d out_k/dp_m.

Two forms of the tangent (:func:`sensitivity_form` chooses, with the measured figures):

* *expanded* (:func:`sensitivity_blocks`): the n x 2n entries of dr/dy and the n x np of dr/dp
  as expressions, evaluated once per right-hand side call whatever the number of directions;
  each direction then costs a 2n x n product. Not for rigid-body trees.
* *direction* (:func:`direction_tangent`): the right-hand side kernel as a straight-line
  :class:`~lagcodegen.formulation.tangent.Program` (hash-consed, the run-time parameters counted
  as differentiation variables), and per direction ONE forward-mode sweep of it seeded with
  (dy, dp) = (s, s', e_k): the sweep gives dM and dF, hence g = dM a - dF = (dr/dy)(s, s') +
  dr/dp_k (a held fixed), and M s'' = -g is solved with the factorization that gave q''. Its cost per direction
  is a small multiple of the right-hand side's, independent of the size of dr/dy; it works on
  the recorded programs of rigid-body trees as on closed forms (parameters inside link
  inertias included: they are symbols of the program like any other).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import symengine as se

from ..errors import ModelError
from .kernels import Block, model_blocks, require_symmetric, residual_derivatives, substituter
from .scene import Scene
from .tangent import Program, _live_ops, build_program


def sensitivity_blocks(scene: Scene) -> dict[str, Block]:
    """The kernels ``rhs``, ``tangent`` and ``out`` of the sensitivity equations of ``scene``
    (module docstring). Rigid-body trees (whose M and F are programs, not expressions) raise
    ModelError."""
    eom = scene.eom
    model = eom.model
    if eom.tree is not None:
        raise ModelError(f"model {model.name!r}: sensitivities of a rigid-body tree model are not generated "
                         "(its M and F are programs, not expressions)")
    if eom.general:
        raise ModelError(f"model {model.name!r} has generalized speeds: the expanded form of the sensitivities "
                         "is not generated for it (the per-direction form is: form='direction' or 'auto')")
    require_symmetric(eom, "sensitivities")
    n = model.n
    c = substituter(scene)
    rhs = model_blocks(dataclasses.replace(scene, jacobian=False))["rhs"]
    y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    dr = residual_derivatives(eom)
    tangent = Block()
    for j in range(2 * n):
        for i in range(n):
            e = c(dr(i, j))
            if e != 0:
                tangent.add(("G", i, j), e)
    for k, par in enumerate(params):
        for i in range(n):
            r = sum((eom.M_se[i][j] * a[j] for j in range(n)), se.Integer(0)) - eom.F_se[i]
            tangent.add_partials(r, [par], c, lambda _, k=k, i=i: ("P", k, i))
    for k, (_, rate) in enumerate(eom.quadratures):
        tangent.add_partials(rate, y, c, lambda j, k=k: ("Z", k, j))
        tangent.add_partials(rate, params, c, lambda m, k=k: ("Zp", k, m))
    out = output_block(scene)
    _closed_form(model, tangent)
    return {"rhs": rhs, "tangent": tangent, "out": out}


def _closed_form(model, block: Block) -> None:
    bad = [e for e in block.exprs if e.atoms(se.Derivative, se.Subs)]
    if bad:
        raise ModelError(f"model {model.name!r}: sensitivities need derivatives of {bad[0]}, which symengine "
                         "cannot take in closed form")


def output_block(scene: Scene) -> Block:
    """The kernel ``out`` of the module docstring: ("Oy", k, i) = d out_k/dy_i, ("Op", k, m) =
    d out_k/dp_m (every form of the tangent uses it)."""
    eom = scene.eom
    model = eom.model
    c = substituter(scene)
    out = Block()
    if eom.general:  # y = (q, v, z): differentiated in the array symbols (q' inside: the kinematics)
        ny = model.nq + model.nv + len(eom.quadratures)
        states = [se.Symbol(f"y[{i}]") for i in range(ny)]
        params = [se.Symbol(f"p[{m}]") for m in range(len(scene.runtime_parameters))]
        for k, o in enumerate(scene.output_list()):
            e = c(o.expr)
            out.add_partials(e, states, lambda x: x, lambda i, k=k: ("Oy", k, i))
            out.add_partials(e, params, lambda x: x, lambda m, k=k: ("Op", k, m))
        _closed_form(model, out)
        return out
    y = [se.Symbol(s.name) for s in model.coords] + [se.Symbol(s.name) for s in model.speeds]
    params = [se.Symbol(name) for name in scene.runtime_parameters]
    states = y + [se.Symbol(name) for name, _ in eom.quadratures]
    for k, o in enumerate(scene.output_list()):
        out.add_partials(o.expr, states, c, lambda i, k=k: ("Oy", k, i))
        out.add_partials(o.expr, params, c, lambda m, k=k: ("Op", k, m))
    _closed_form(model, out)
    return out


@dataclass
class DirectionTangent:
    """The per-direction form (module docstring): ``program`` the right-hand side kernel's
    values (its partial-derivative values appended after ``program.n_rhs``), ``targets``
    (target, atom) of M's upper triangle ("M", i, j), F ("F", i) and the quadrature rates
    ("ydot", 2n + k).

    The sweep is linear in its seed (dy, dp) and is split accordingly: ``state_ops`` the sweep
    seeded by dy = (s, s') (the symbols ``sk[i]``, i < 2n; the parameters constant), run for
    every direction, and ``param_ops[m]`` the sweep seeded by dp = e_m (y constant), run for a
    direction of parameter m only and over the values that depend on p_m only. Operations, in
    order, over the values ``v[k]`` and the accelerations ``a[i]``: ("d", k, e) the local
    tangent ``d<k>`` of value k, ("g", i, e) ``g[i] += e`` (g = dM a - dF), ("z", k, e)
    ``dz[k] += e``, the rate of quadrature k's sensitivity."""

    n: int
    nz: int
    np: int
    program: Program
    targets: list
    state_ops: list
    param_ops: list
    #: The speeds of a model with generalized speeds (y = (q, v, z), n = nq), else None. Its
    #: ("z", r, e) operations are then ``dk[r] += e`` for the rows r of ydot given in closed form
    #: (the kinematic rates r < n, the quadratures r >= n + nv), seeded by sk[i], i < n + nv.
    nv: int | None = None

    def size(self) -> int:
        """Operand terms of the state sweep (a measure of its cost per direction)."""
        return sum(len(se.Add.make_args(e)) for _, _, e in self.state_ops)


def _sweep(prog: Program, targets: list, n: int, columns: frozenset, seeds: dict, zero: int | None = None) -> list:
    """The forward-mode sweep of ``prog`` seeded by ``seeds`` (atom -> its tangent) along the
    dependency ``columns`` (a value is differentiated if it depends on one): the operations of
    :class:`DirectionTangent` (``zero``: the row of ydot of the "z" operations' index 0, 2n
    unless given)."""
    zero = 2 * n if zero is None else zero

    def tangent_of(u):
        if u in seeds:
            return seeds[u]
        k = prog.index(u)
        if k is not None and k < prog.n_rhs and prog.deps[k] & columns:
            return se.Symbol(f"d{k}")
        return None
    ops = []
    for k in range(prog.n_rhs):
        if not prog.deps[k] & columns:
            continue
        terms = []
        for u, coef, atom in prog.partials[k]:
            du = tangent_of(u)
            if du is not None:
                terms.append((coef if atom is None else coef * atom) * du)
        if terms:
            ops.append(("d", k, se.Add(*terms)))
    a = [se.Symbol(f"a[{i}]") for i in range(n)]
    for target, atom in targets:
        du = tangent_of(atom)
        if du is None:
            continue
        kind, *idx = target
        if kind == "M":
            i, j = idx
            ops.append(("g", i, du * a[j]))
            if i != j:
                ops.append(("g", j, du * a[i]))
        elif kind == "F":
            ops.append(("g", idx[0], -du))
        else:
            ops.append(("z", idx[0] - zero, du))
    return _live_ops(ops)


def direction_tangent(scene: Scene) -> DirectionTangent:
    """The per-direction form of the sensitivity equations of ``scene`` (module docstring): one
    forward-mode sweep of the right-hand side program per direction. Works for rigid-body trees
    (their recorded program, parameters inside link inertias included) as for closed forms."""
    eom = scene.eom
    require_symmetric(eom, "sensitivities")
    n, nz, npar = eom.model.n, len(eom.quadratures), len(scene.runtime_parameters)
    rhs = model_blocks(dataclasses.replace(scene, jacobian=False))["rhs"]
    # Generalized speeds: columns (q, v), nq + nv of them; the "z" operations index ydot's rows.
    nv, zero = (eom.model.nv, 0) if eom.general else (None, 2 * n)
    ncol = n + (n if nv is None else nv)
    prog, targets = build_program(rhs, n, nparams=npar, nv=nv)
    try:
        prog.finish_rhs()
    except ModelError as exc:
        raise ModelError(f"model {eom.model.name!r}: sensitivities: {exc}") from None
    state = _sweep(prog, targets, n, frozenset(range(ncol)),
                   {se.Symbol(f"y[{i}]"): se.Symbol(f"sk[{i}]") for i in range(ncol)}, zero)
    params = [_sweep(prog, targets, n, frozenset((ncol + m,)), {se.Symbol(f"p[{m}]"): se.Integer(1)}, zero)
              for m in range(npar)]
    return DirectionTangent(n, nz, npar, prog, targets, state, params, nv)


#: Choices of the tangent's form (:func:`sensitivity_form`).
SENSITIVITY_FORMS = ("auto", "expanded", "direction")


def sensitivity_form(scene: Scene) -> str:
    """The form the generated sensitivities take (module docstring): "direction", for every model.

    Rule and figures. One call of ``sens_rhs`` with ns directions (the first ones of the run-time
    parameters, then initial values), nanoseconds of thread CPU time, gcc -O2, best of 5 x 200 000
    calls, on a 2-core machine under a load of ~9 (direction / expanded)::

        model               n  np   ns=0      ns=1      ns=3       ns=10
        pendulum            1   3   43/55     62/70     66/84      120/132
        damped pendulum     1   4   44/67     63/99     86/97      169/145
        double pendulum     2   5   92/169    152/218   250/297    460/574
        3-link chain        3   7   137/324   237/410   434/491    1161/878
        5-link chain        5  11   430/988   840/1039  1480/1220  2695/2269

    The sweep costs about one right-hand side per direction; the expanded form pays 1.5 to 2.5
    right-hand sides for dr/dy and dr/dp at every call whatever ns, then a 2n x n product per
    direction. So the per-direction form is the cheaper for ns <= 3 on every model measured, the
    tiny ones included (where the two are within noise); the expanded one overtakes it only at
    ns ~ 10 on the chains (and from ns ~ 4 on the 5-link chain), where its symbolic dr/dy and the
    compilation of its n x 2n expressions grow like n^3 besides. Rigid-body trees have only the
    per-direction form. The expanded form stays available (``form="expanded"`` of
    :func:`lagcodegen.codegen.sensitivity.sensitivity_source`) as the second method the tests
    check the sweep against."""
    return "direction"
