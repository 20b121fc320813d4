"""The CVODE family: its options object (:mod:`.options`), the native runner (:mod:`.native`,
the runtime's C drivers) and the ensemble runner (:mod:`.ensemble`); scikit-sundae
(:mod:`lagcodegen.solvers.sksundae`) is its second backend."""

from .native import band_widths  # noqa: F401
from .options import CVODE  # noqa: F401

__all__ = ["CVODE", "band_widths"]
