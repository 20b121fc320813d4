"""The model stage: coordinates, parameters, bodies, energies and forces (:mod:`.model`),
events (:mod:`.events`), the catalogue of outputs (:mod:`.outputs`), models written with
``sympy.physics.mechanics`` (:mod:`.mechanics`) and a library of classic systems (:mod:`.systems`)."""

from ..util import check_finite  # noqa: F401
from .events import Event, EventRecord  # noqa: F401
from .bodies import Joint, Link, Placement  # noqa: F401
from .model import Model, Particle, PlanarBody, Point, RigidBody  # noqa: F401
