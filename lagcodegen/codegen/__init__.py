"""Code generation: the language-neutral kernels of :mod:`lagcodegen.formulation` printed as C99
(:mod:`.c`) or Fortran 2008 (:mod:`.fortran`) through the jinja2 templates, the cffi
declarations (:mod:`.cffi_decl`) and the bundles for other projects' builds (:mod:`.bundle`);
the C of the Taylor integrator and of its sensitivities (:mod:`.taylor`).

Both print one operation tree (:mod:`.ir`; the program form laid out by :mod:`.program`), and
the procedures of the dense solves (:mod:`.linalg`, in the loops of :mod:`.procedure`) with
their procedure printers (:mod:`.c_procedure`, :mod:`.fortran_procedure`). A
language is a backend class with ``generate(scene)``, ``check_prefix(prefix, suffix)`` and
``constrained_source(blocks, ctx)``, registered by name in :mod:`.languages`; callers name a
language and never test for one.
"""

from .c import generate_c  # noqa: F401
from .fortran import generate_fortran  # noqa: F401
from .languages import LANGUAGES, check_language, generate_code  # noqa: F401
from .record import GeneratedCode  # noqa: F401
