"""The model-independent runtime's C sources as files of this folder (package data), compiled as
they are: the native SUNDIALS drivers (``lcg_cvode.c``, ``lcg_cvc.c``, ``lcg_ida.c``), the Taylor
driver (``lcg_taylor.c`` with its body ``lcg_taylor_driver.h``: the step that the Taylor stepper
shares), the steppers of the integrator object (``lcg_taylor_stepper.c``,
``lcg_cvode_stepper.c``, ``lcg_cvc_stepper.c``, ``lcg_ida_stepper.c``, ``lcg_cvsens_stepper.c``: each
one translation unit with the driver it includes, built as a module of its own; their lifecycle, the caller's memory, the
advance over a grid or by one step and its end, once in ``lcg_stepper.h``), the model tables they read
(``lcg_model.h``, ``lcg_dae_model.h``), run control (``lcg_control.h``), the ensemble pool (``lcg_pool.h``), the
SUNDIALS plumbing (``lcg_sundials.h``, ``sundials_api.h``). What depends on the build (the SUNDIALS
index type, the version) and the result codes come from small generated headers (``lcg_config.h``,
``lcg_codes.h``) that the build writes beside them."""

from __future__ import annotations

from pathlib import Path

FOLDER = Path(__file__).resolve().parent


def source(name: str) -> str:
    """The text of the runtime file ``name`` (e.g. ``"lcg_cvode.c"``)."""
    return (FOLDER / name).read_text()


def sources(names) -> dict[str, str]:
    """{name: text} of the runtime files ``names``."""
    return {name: source(name) for name in names}
