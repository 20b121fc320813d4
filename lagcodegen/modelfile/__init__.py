"""Declarative model files: a mechanical model and its simulation settings in TOML,
parsed through a whitelisted ``ast`` walk, never executed.

A build step can describe a model without writing Python::

    [model]
    name = "double_pendulum"              # optional; default: the file's stem (or "model")
    coordinates = ["theta1", "theta2"]

    [parameters]                          # name = default value (finite number)
    l1 = 1.0
    g = 9.81

    [inputs]                              # input signals u(t): name = default value; used in
    F = 0.0                               # expressions as parameters are (Model.input)

    [units]                               # optional units (documentation; FMUs carry them):
    theta1 = "rad"                        # name of a coordinate, parameter or input = "unit"

    [[points]]                            # optional named points (anchors, attachment points)
    name = "anchor"
    position = [0, 0]

    [[particles]]                         # name, mass, position (1, 2 or 3 components)
    name = "bob1"
    mass = "m1"
    position = ["l1*sin(theta1)", "-l1*cos(theta1)"]

    [[planar_bodies]]                     # name, mass, inertia, position (2), angle
    [[rigid_bodies]]                      # name, mass, inertia, position (3), orientation
                                          # inertia: 3 principal moments or a 3x3 array;
                                          # orientation: 3x3 array (body -> world rotation)
    [gravity]                             # g; up optional (default: last axis)
    g = "g"
    up = [0, 1]

    [[springs]]                           # a, b: point names or positions; k; rest_length, label optional
    a = "bob1"
    b = "anchor"
    k = "k"

    [[dampers]]                           # point, c; b (second point), label optional
    [[forces]]                            # point, vector; label optional
    [[generalized_forces]]                # coordinate, expr; label optional
    [energy]                              # kinetic, potential, dissipation (each optional)
    [outputs]                             # name = "expression" (user outputs)

    [constraints]                         # optional (notes, sec. 4); every key optional
    holonomic = ["x**2 + y**2 - l**2"]    # f(q, t) = 0 (eq. 4.1)
    nonholonomic = [                      # A . q' + A0 = 0 (eq. 4.3); A0 optional (default 0)
        { A = ["sin(th)", "-cos(th)", 0], A0 = 0 },      # one coefficient per coordinate, or
        { coefficients = { x = 1, phi = "-R" } },        # by coordinate name (missing ones 0)
    ]
    inequalities = ["y + 2*l"]            # g(q, t) >= 0: monitored (terminal event ineq_<k>)
    integrable = "error"                  # or "allow" (keep an integrable Pfaffian row)

    [[events]]                            # root functions, every kind of model
    name = "leave"
    expr = "lambda_0"                     # q, <coord>_dot, t, parameters, multipliers lambda_<j> (or outputs)
    direction = -1                        # -1 decreasing, 0 both, 1 increasing (default 0)
    terminal = true                       # default true

    [simulation]                          # every key optional
    t_start = 0.0
    t_end = 20.0
    n_out = 1001
    method = "adams"                      # or "bdf"
    rtol = 1e-8
    atol = 1e-10
    max_steps = 1000000                   # step budget of the whole run (1 to 2**31 - 1)
    initial = { theta1 = 1.0, theta2 = 0.5, theta1_dot = 0.0 }
    outputs = ["energy", "positions"]     # scene outputs (see lagcodegen.formulation.scene.Scene)
    runtime_parameters = ["g"]            # default: every parameter stays adjustable
    parameters = { g = 1.62 }             # overrides of the parameter defaults
    jacobian = true
    formulation = "index1"                # constrained files: "index1" (default), "ggl", "minimal"
    baumgarte = [5.0, 5.0]                # index1: (alpha, beta), [0, 0] none; default "auto"
    projection = false                    # index1: project after each step (needs method "bdf")

Each table maps onto one :class:`~lagcodegen.model.Model` call (``particle``, ``point``,
``planar_body``, ``rigid_body``, ``gravity``, ``spring``, ``damper``, ``force``,
``generalized_force``, ``kinetic_energy``, ``potential_energy``, ``dissipation``,
``output``; ``[inputs]``: ``input``). Where a point is expected (``a``, ``b``, ``point``), a
string names a point (``[[points]]`` or a body) and an array gives a position.

Expressions are TOML numbers or strings such as ``"-l1*cos(theta1)"``. A string is parsed
by :func:`ast.parse` and converted by walking a whitelist of node types: numbers, names,
``+ - * / **``, unary ``-``/``+`` and calls of ``sin cos tan asin acos atan atan2 sinh
cosh tanh exp log sqrt abs sign``. Names are the coordinates, their velocities
``<coord>_dot`` (only in forces, kinetic energy, dissipation, outputs and events), the parameters,
the inputs, ``t`` and ``pi``. Nothing is ever evaluated: no ``eval``, no ``sympify`` of raw text.
Parameter values, ``initial`` values and ``t_start``/``t_end``/``rtol``/``atol`` may be
constant expressions too (``"pi/2"``).

With a ``[constraints]`` table, :attr:`ModelFile.constrained` is the
:class:`~lagcodegen.theory.constraints.ConstrainedSystem` (constraint j, holonomic ones first,
has the multiplier ``lambda_<j>``, counted from 0), and :func:`lagcodegen.compile_file` goes
through :func:`lagcodegen.compile_constrained`. Constrained runs output the requested
outputs (default: energy) plus ``lambda`` (not in minimal coordinates), ``residuals`` and, with
inequality constraints, ``inequalities``. :attr:`ModelFile.events` holds the ``[[events]]`` of
every kind of file as :class:`~lagcodegen.model.events.Event` items: compiled in for
constrained files, handed to each run (:meth:`ModelFile.simulate`) for the others.

Every problem raises :class:`ModelFileError` (a :class:`~lagcodegen.errors.ModelError`)
naming the file, the line when it can be found, the key path (``particles[1].position[0]``)
and the offending token.

Every table and key, with its type, default and meaning, is declared in :mod:`.schema`, which
the loader validates against; ``docs/model-files.md`` is generated from it
(``python tools/model_file_reference.py``).

The package, one job a module: :mod:`.schema` (the tables and keys as data),
:mod:`.expressions` (the expression whitelist),
:mod:`.locate` (finding the line of a problem in the TOML text), :mod:`.values` (typed values
read with located errors), :mod:`.loader` (the sections, into a Model and its settings),
:mod:`.document` (the loaded :class:`ModelFile` and how it runs) and :mod:`.formats` (the
loader of a path by its suffix: :func:`load_model_path`, the one entry of the command line).
"""

from ..theory.constraints import FORMULATIONS
from .document import ModelFile, SimulationSettings, constrained_method, constrained_outputs
from .expressions import FUNCTIONS, ExpressionError, parse_expression
from .formats import LOADERS, load_model_path
from .loader import load_model, loads_model
from .locate import ModelFileError

__all__ = ["FORMULATIONS", "FUNCTIONS", "LOADERS", "ExpressionError", "ModelFile", "ModelFileError",
           "SimulationSettings", "constrained_method", "constrained_outputs", "load_model", "load_model_path",
           "loads_model", "parse_expression"]
