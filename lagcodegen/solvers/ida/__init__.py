"""The IDA family: its options object (:mod:`.options`), the native runner (:mod:`.native`, the
runtime's GGL driver) and the ensemble runner (:mod:`.ensemble`); scikit-sundae
(:mod:`lagcodegen.solvers.sksundae`) is its second backend."""

from .options import IDA  # noqa: F401

__all__ = ["IDA"]
