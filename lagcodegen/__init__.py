"""lagcodegen: Lagrangian mechanics -> standalone C code -> SUNDIALS integration.

Pipeline: model -> derivation -> scene -> codegen (templates) -> build (cffi) -> solve -> result.
"""

__version__ = "0.1.0"

from .errors import (CompileError, DerivationError, LagcodegenError, ModelError,  # noqa: F401
                     SingularMassMatrixError, SolverError)
from .model import Model  # noqa: F401
from .derivation import EquationsOfMotion, derive  # noqa: F401
