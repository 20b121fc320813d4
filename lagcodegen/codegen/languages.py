"""The registry of languages the model code can be generated in: a name -> its backend class.

A backend class (:class:`.c.CBackend`, :class:`.fortran.FortranBackend`) has ``generate(scene)``
-> :class:`~.record.GeneratedCode`, ``check_prefix(prefix, suffix)`` and
``constrained_source(blocks, ctx)`` and ``impact_source(blocks, contact, ctx)`` (the contact
functions of a system with contacts, with their C tables) -> {file name: text}, and prints the operation tree of
:mod:`.ir` (and the program form of :mod:`.program`) with its own printer class; the procedures
of :mod:`.procedure` (the LU solve of :mod:`.linalg`) with its procedure printer. A backend class
also answers what bundles and builds ask of a language (``suffix``, ``title``, ``link_libs``,
``c_sources``, the compiler's ``compiler_env``/``default_compiler``, ``make_variables``,
``cmake_languages``, ``cmake_library_properties``, ``module_files(stem)``), and its templates
folder holds the language's fragments of a bundle (templates/<lang>/bundle/). Adding a language
is one backend module with its printer and backend class, a procedure printer (registered in
:func:`.templates.environment`), its templates, and one line here.
"""

from __future__ import annotations

from ..errors import ModelError
from ..formulation.scene import Scene
from .c import CBackend
from .dynamics import inverse_dynamics_files
from .fortran import FortranBackend
from .ir import deep_recursion
from .record import GeneratedCode

#: The backend classes by language name.
BACKENDS = {cls.name: cls for cls in (CBackend, FortranBackend)}
LANGUAGES = tuple(BACKENDS)


def backend(lang: str):
    """The backend of ``lang`` (an instance of its class); ModelError naming the choices if unknown."""
    check_language(lang)
    return BACKENDS[lang]()


def generate_code(scene: Scene, lang: str = "c") -> GeneratedCode:
    """The model code of ``scene`` in ``lang``: "c" (:func:`.c.generate_c`) or "fortran"
    (:func:`.fortran.generate_fortran`, same functions and the same header); a rigid-body tree's
    inverse dynamics comes with both, in C (:mod:`.dynamics`)."""
    with deep_recursion():
        code = backend(lang).generate(scene)
        if scene.eom.tree is not None:
            code.files.update(inverse_dynamics_files(scene, code))
    return code


def file_backend(name: str):
    """The backend whose model sources end like the file ``name`` (``.c``, ``.f90``), or None."""
    for cls in BACKENDS.values():
        if name.endswith(cls.suffix):
            return cls()
    return None


def check_language(lang: str) -> None:
    """Raise ModelError unless ``lang`` names a registered language."""
    if not isinstance(lang, str) or lang not in BACKENDS:
        raise ModelError(f"unknown language {lang!r} (choose from {', '.join(LANGUAGES)})")
