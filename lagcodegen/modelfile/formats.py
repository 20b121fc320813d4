"""Model files by format: which loader reads a path, chosen by its suffix.

One job: the one dispatch from a model file's path to its :class:`ModelFile`
(:func:`load_model_path`). A new format is one entry of :data:`LOADERS`: a function of the
path returning a :class:`ModelFile`, a :class:`~lagcodegen.model.model.Model` or a
:class:`~lagcodegen.theory.constraints.ConstrainedSystem` (the last two run with the default
:class:`SimulationSettings`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable, Mapping

from ..errors import ModelError
from ..model.model import Model
from ..theory.constraints import ConstrainedSystem
from .document import ModelFile, SimulationSettings
from .loader import load_model
from .urdf import load as load_urdf

#: Suffix (lower case, with the dot) -> loader of a model file with that suffix.
LOADERS: dict[str, Callable[[Path], Any]] = {
    ".toml": load_model,
    ".urdf": load_urdf,  # a robot: its movable joints as coordinates (lagcodegen.modelfile.urdf)
}


def as_model_file(value: Any, path: Path, what: str) -> ModelFile:
    """``value`` (a ModelFile, a ConstrainedSystem or a Model) as a :class:`ModelFile` read from
    ``path``; ``what`` names the source in the error raised for anything else."""
    if isinstance(value, ModelFile):
        return value
    if isinstance(value, ConstrainedSystem):
        return ModelFile(model=value.model, simulation=SimulationSettings(), path=path, constrained=value)
    if isinstance(value, Model):
        return ModelFile(model=value, simulation=SimulationSettings(), path=path)
    raise ModelError(f"{what} returned {type(value).__name__}, not a Model, ConstrainedSystem or ModelFile")


def load_model_path(path: str | os.PathLike, *, urdf: Mapping[str, Any] | None = None) -> ModelFile:
    """The model file at ``path``, read by the loader of its suffix (:data:`LOADERS`); ``urdf``:
    the keywords of :func:`lagcodegen.modelfile.urdf.load` for a ``.urdf`` file (``floating``,
    ``mimic``, ``limits``, ``lock``, ...), refused for other files."""
    path = Path(path)
    suffix = path.suffix.lower()
    loader = LOADERS.get(suffix)
    if loader is None:
        known = ", ".join(sorted(LOADERS))
        raise ModelError(f"{path}: not a model file lagcodegen reads (suffixes: {known}; or FILE.py:FUNCTION)")
    if urdf:
        if suffix != ".urdf":
            raise ModelError(f"{path}: URDF options ({', '.join(sorted(urdf))}) apply to .urdf files only")
        return as_model_file(load_urdf(path, **urdf), path, str(path))
    return as_model_file(loader(path), path, str(path))
