"""Declarative TOML model files: parsed through a whitelisted ``ast`` walk, never executed."""

from .loader import (FORMULATIONS, FUNCTIONS, ExpressionError, ModelFile, ModelFileError,  # noqa: F401
                     SimulationSettings, constrained_method, constrained_outputs, load_model, loads_model,
                     parse_expression)
from .loader import __all__  # noqa: F401
