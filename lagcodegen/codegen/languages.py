"""The registry of languages the model code can be generated in."""

from __future__ import annotations

from ..errors import ModelError
from ..formulation.scene import Scene
from . import c, fortran
from .dynamics import inverse_dynamics_files
from .record import GeneratedCode

#: The language modules by name: each has generate(scene) -> GeneratedCode,
#: check_prefix(prefix, suffix) and constrained_source(blocks, ctx) -> {file name: text}.
LANGUAGE_MODULES = {"c": c, "fortran": fortran}
LANGUAGES = tuple(LANGUAGE_MODULES)


def generate_code(scene: Scene, lang: str = "c") -> GeneratedCode:
    """The model code of ``scene`` in ``lang``: "c" (:func:`.c.generate_c`) or "fortran"
    (:func:`.fortran.generate_fortran`, same functions and the same header)."""
    check_language(lang)
    code = LANGUAGE_MODULES[lang].generate(scene)
    if scene.eom.tree is not None:  # a rigid-body tree: its inverse dynamics in C (.dynamics)
        code.files.update(inverse_dynamics_files(scene, code))
    return code


def check_language(lang: str) -> None:
    """Raise ModelError unless ``lang`` names a registered language."""
    if not isinstance(lang, str) or lang not in LANGUAGE_MODULES:
        raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
