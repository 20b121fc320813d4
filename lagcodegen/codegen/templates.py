"""The jinja2 environment of every generated file: templates by language and purpose."""

from __future__ import annotations

import functools
from pathlib import Path

import jinja2

from . import linalg
from .c_procedure import CProcedurePrinter
from .fortran_procedure import FortranProcedurePrinter
from .signatures import c_signature, fortran_signature


def templates_dir() -> Path:
    """Folder holding the jinja2 templates (installed package data, or the source tree)."""
    here = Path(__file__).resolve().parents[1]  # the lagcodegen package
    for cand in (here / "templates", here.parent / "templates"):
        if (cand / "c" / "model.c.j2").is_file():
            return cand
    raise FileNotFoundError(f"lagcodegen templates not found next to {here}")


def _bytecode_cache():
    """jinja2's FileSystemBytecodeCache in its default folder, or None where it cannot be used."""
    try:
        return jinja2.FileSystemBytecodeCache()
    except (OSError, RuntimeError):  # no private temporary folder to be had: compile every time
        return None


@functools.lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The environment of every template, with :func:`~.signatures.c_signature`,
    :func:`~.signatures.fortran_signature`, ``c_procedure(procedure, printer=None, **options)`` and
    ``fortran_procedure(procedure, printer=None, **options)`` (a procedure of :mod:`.linalg` made
    with ``options``, printed by that language's printer made with ``printer``, a dict of its
    options) as globals: one per process, so that each template is
    compiled once (tens of milliseconds each, a large part of a small model's first build), and
    jinja2's own bytecode cache (a folder of the user's own in the temporary directory, which
    jinja2 checks for ownership and mode 0700) keeps the compiled templates for the next process."""
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        bytecode_cache=_bytecode_cache(),
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
        undefined=jinja2.StrictUndefined)
    env.globals.update(c_signature=c_signature, fortran_signature=fortran_signature,
                       c_procedure=lambda procedure, printer=None, **options: CProcedurePrinter(
                           **(printer or {})).text(linalg.PROCEDURES[procedure](**options)),
                       fortran_procedure=lambda procedure, printer=None, **options: FortranProcedurePrinter(
                           **(printer or {})).text(linalg.PROCEDURES[procedure](**options)))
    return env


