"""Exceptions raised by lagcodegen. Every error names what was wrong and where."""

from __future__ import annotations


class LagcodegenError(Exception):
    """Base class of all lagcodegen errors."""


class ModelError(LagcodegenError, ValueError):
    """The model is ill-formed: unknown symbol, unused coordinate, bad value...

    ``location`` says where (a model file and key, or a Python call).
    """

    def __init__(self, message: str, location: str | None = None):
        self.location = location
        super().__init__(f"{location}: {message}" if location else message)


class DerivationError(LagcodegenError):
    """The equations of motion cannot be formed (e.g. T not quadratic in q')."""


class CompileError(LagcodegenError):
    """The C compiler failed. ``output`` holds what the compiler printed."""

    def __init__(self, message: str, command: list[str], output: str):
        self.command = command
        self.output = output
        super().__init__(f"{message}\ncommand: {' '.join(command)}\ncompiler output:\n{output}")


class SolverError(LagcodegenError, RuntimeError):
    """Integration failed. ``t`` is the time reached, ``flag`` the SUNDIALS flag."""

    def __init__(self, message: str, t: float, flag: int = 0, result=None):
        self.t = t
        self.flag = flag
        self.result = result
        super().__init__(f"{message} (integration stopped at t = {t:.17g})")


class SingularMassMatrixError(SolverError):
    """The mass matrix M(q, t) is singular (not invertible) at the time reported."""
