"""What the pickle of a compiled simulation carries to an executor's worker: its generated
sources always (the symbolic scene is many times their size), its scene too where the worker's
runs need it (the Taylor method, events, sensitivities): :func:`with_scene`."""

from __future__ import annotations

from ..codegen.record import GeneratedCode
from ..errors import LagcodegenError


def scene_code(sim) -> GeneratedCode | None:
    """The generated code of a compiled simulation that has one: a compiled scene's, or that of
    the compiled model under a constrained system; else None."""
    code = getattr(sim, "code", None)
    if isinstance(code, GeneratedCode):
        return code
    code = getattr(getattr(sim, "compiled", None), "code", None)
    return code if isinstance(code, GeneratedCode) else None


class WithScene:
    """A compiled simulation whose pickle carries its symbolic scene too, once: unpickled, it is
    the simulation itself (rebuilt from its sources) with the scene restored, so that what needs
    the scene (the Taylor method, events, sensitivities) runs there. Make it with
    :func:`with_scene`; in this process, ``.sim`` is the simulation."""

    __slots__ = ("sim",)

    def __init__(self, sim):
        self.sim = sim

    def __reduce__(self):
        code = scene_code(self.sim)
        return _restore_scene, (self.sim, None if code is None else code.scene)


def with_scene(sim) -> WithScene:
    """``sim`` (a compiled model, or a constrained simulation) to be pickled with its scene, for a
    process that runs it with the Taylor method, events or sensitivities (an executor's worker:
    :func:`lagcodegen.solvers.ensemble.run_chunks` sends such runs this way). LagcodegenError if
    ``sim`` has no scene to carry (it was itself unpickled without one, or assembled by hand)."""
    code = scene_code(sim)
    if code is not None and code.scene is None and code.rederive is not None:
        code.scene = code.rederive()  # code from the cache of a model file: its scene derived again
    if code is not None and code.scene is None:
        raise LagcodegenError(f"model {code.model_name!r} has no symbolic scene to carry (it was unpickled without "
                              "one, or assembled by hand): compile it again in this process")
    return WithScene(sim)


def _restore_scene(sim, scene):
    code = scene_code(sim)
    if code is not None and code.scene is None and scene is not None:
        code.scene = scene
    return sim
