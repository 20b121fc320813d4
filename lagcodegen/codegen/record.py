"""The record of one scene's generated files (:class:`GeneratedCode`) and the layout shared by
every language's header (:func:`header_context`)."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..formulation.kernels import mass_matrix_is_diagonal
from ..formulation.scene import Scene
from ..util import atomic_write
from ..version import __version__


@dataclass(frozen=True)
class DaeLayout:
    """The layout of a constrained system's functions (``<prefix>_dae.h``), which its function
    table ``<prefix>_dae_table.c`` (``lcg_dae_model.h``) states and the build checks: nq
    coordinates, nj equality constraints (njh holonomic), ng GGL unknowns, nout outputs, nroot
    root functions; ``ggl``: the GGL residual is compiled, ``ggl_jac``: its Jacobian too; ``nv``:
    the generalized speeds (None: nq, the speeds are the coordinates' rates), the state
    y = (q, v) of nq + nv values (the table's ny)."""

    nq: int
    nj: int
    njh: int
    ng: int
    np: int
    nout: int
    nroot: int
    ggl: bool
    ggl_jac: bool
    nv: int | None = None


@dataclass
class GeneratedCode:
    """Generated C sources of one scene: ``files`` maps file name -> text."""

    prefix: str
    model_name: str
    n: int
    state_names: list[str]
    param_names: list[str]
    param_defaults: list[float]
    output_names: list[str]
    jacobian: bool
    nz: int = 0  # quadrature states appended after (q, q'), e.g. reconstructed ignorable coordinates
    files: dict[str, str] = field(default_factory=dict)
    # For build(): extra cffi declarations, extra headers the cffi module includes, and
    # SUNDIALS libraries besides CVODE (e.g. ("ida",)) needed by extra drivers in ``files``.
    cdef_extra: str = ""
    cffi_headers: list[str] = field(default_factory=list)
    sundials_libs: tuple[str, ...] = ()
    # Structural nonzero pattern of df/dy (ny x ny booleans, Scene.jacobian_pattern), or None
    # when unknown (then the band solver probes it numerically); sparse_jacobian: the files
    # <prefix>_sparse.[ch] with <prefix>_jac_sparse are in ``files``.
    jac_pattern: object = None
    sparse_jacobian: bool = False
    # Parameters folded into the code as constants, with their values.
    folded: dict = field(default_factory=dict)
    # Constrained code (<prefix>_dae.h and its implementation in ``files``): its layout, which
    # makes build() compile the function table <prefix>_dae_table.c for the runtime's constrained
    # drivers; None for other code.
    dae: DaeLayout | None = None
    # Sources cut into groups of functions (file name -> number of groups): compiled as one
    # translation unit, or by build() as several objects at once (-DLCG_PARTS, -DLCG_PART).
    split: dict = field(default_factory=dict)
    # The scene the code was generated from (for further code of the same scene, e.g. the
    # Taylor integrator), or None for code assembled by hand.
    scene: object = field(default=None, repr=False, compare=False)
    # Code loaded from the cache without its scene (:func:`lagcodegen.api.compile_urdf`): a
    # function deriving the scene again where a run needs it (never pickled).
    rederive: object = field(default=None, repr=False, compare=False)
    # The run-time parameters that are input signals u(t) (Model.input), in p order: an FMU
    # declares them as inputs.
    input_names: list[str] = field(default_factory=list)
    # Generalized speeds (q' = k(q, v, t), y = (q, v, z)): their number; None: v = q' (nv = n).
    nv: int | None = None
    # The neutral configuration (quaternions' scalar parts 1) where it is not all zeros: the q a
    # run starts from where none is given.
    q_neutral: list | None = None

    @property
    def ny(self) -> int:
        return self.n + self.speeds + self.nz

    @property
    def speeds(self) -> int:
        """The number of speeds nv (= n unless the model has generalized speeds)."""
        return self.n if self.nv is None else self.nv

    @property
    def np(self) -> int:
        return len(self.param_names)

    @property
    def nout(self) -> int:
        return len(self.output_names)

    @property
    def header_name(self) -> str:
        return f"{self.prefix}.h"

    @property
    def source_name(self) -> str:
        return f"{self.prefix}.c"

    def write(self, directory: str | os.PathLike) -> list[Path]:
        """Write the files into ``directory``, each atomically (temp file + rename)."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        written = []
        for name, text in self.files.items():
            written.append(atomic_write(out / name, text))
        return written


class CachedCode(GeneratedCode):
    """Generated code read back from the pipeline cache (:func:`lagcodegen.compile_model`,
    :func:`lagcodegen.compile_file`, :func:`lagcodegen.compile_urdf`): no scene was derived in
    this process, and reading ``scene`` derives it again (``rederive()``), once, so that code
    reading ``cm.code.scene`` works as on freshly generated code. ``stored_scene()`` is the
    scene if it was derived, without deriving it."""

    @property
    def scene(self):
        scene = self.__dict__.get("_scene")
        if scene is None and self.__dict__.get("rederive") is not None:
            scene = self.__dict__["_scene"] = self.rederive()
        return scene

    @scene.setter
    def scene(self, value) -> None:
        self.__dict__["_scene"] = value

    def stored_scene(self):
        return self.__dict__.get("_scene")

    @classmethod
    def of(cls, code: GeneratedCode, rederive) -> "CachedCode":
        """``code`` (unpickled, without its scene) whose scene ``rederive()`` derives on demand."""
        values = {f.name: getattr(code, f.name) for f in dataclasses.fields(code) if f.init}
        values.update(scene=None, rederive=rederive)
        return cls(**values)


def stored_scene(code):
    """The scene ``code`` carries now, None if it has none or would derive it on reading (code
    from the pipeline cache: :class:`CachedCode`); never derives."""
    if isinstance(code, CachedCode):
        return code.stored_scene()
    return getattr(code, "scene", None)


def plain_code(code: GeneratedCode) -> GeneratedCode:
    """``code`` without its scene and ``rederive`` (as it is pickled), never deriving the scene."""
    stored = code.stored_scene() if isinstance(code, CachedCode) else code.scene
    if type(code) is GeneratedCode and stored is None and code.rederive is None:
        return code
    values = {f.name: getattr(code, f.name) for f in dataclasses.fields(code) if f.init and f.name != "scene"}
    values.update(scene=None, rederive=None)
    return GeneratedCode(**values)


def scene_of_code(code: GeneratedCode, what: str) -> Scene:
    """The scene ``code`` was generated from, which ``what`` (e.g. "method='taylor'") needs;
    LagcodegenError saying why it is missing: a pickled compiled model carries its generated C
    only, or the code was assembled by hand."""
    scene = getattr(code, "scene", None)
    rederive = getattr(code, "rederive", None)
    if scene is None and rederive is not None:  # code from the cache of a model file: derived again, once
        scene = code.scene = rederive()
    if scene is None:
        from ..errors import LagcodegenError
        raise LagcodegenError(f"{what} needs the symbolic scene of model {code.model_name!r}, which this compiled "
                              "model does not have: a pickled compiled model carries its generated C only (pickle "
                              "lagcodegen.simulation.ode.with_scene(model) to send the scene along), and code "
                              "assembled by hand has none; compile it with lagcodegen.compile_model or "
                              "build(generate_c(scene))")
    return scene


def new_code(scene: Scene) -> GeneratedCode:
    """The GeneratedCode record of ``scene``: layout and names, no files yet."""
    eom = scene.eom
    model = eom.model
    return GeneratedCode(
        prefix=scene.prefix, model_name=model.name, n=model.n, nv=model.nv if model.general else None,
        q_neutral=model.neutral() if any(model.neutral()) else None,
        state_names=[s.name for s in model.coords] + [s.name for s in model.v]
        + [name for name, _ in eom.quadratures],
        param_names=list(scene.runtime_parameters), param_defaults=scene.default_parameters(),
        output_names=[o.name for o in scene.output_list()], jacobian=scene.jacobian, nz=len(eom.quadratures),
        folded=dict(scene.folded), scene=scene, input_names=scene.input_names)


def header_context(scene: Scene, code: GeneratedCode) -> dict:
    """The template context shared by ``c/model.h.j2``, ``c/model.c.j2`` and the Fortran module."""
    return dict(prefix=code.prefix, PREFIX=code.prefix.upper(), version=__version__,
                model_name=code.model_name, n=code.n, nz=code.nz, ny=code.ny, np=code.np, nout=code.nout,
                state_names=code.state_names, param_names=code.param_names,
                folded=sorted(scene.folded.items()), outputs=code.output_names, jacobian=code.jacobian,
                diagonal=mass_matrix_is_diagonal(scene.eom), nv=code.nv,
                lu_only=not getattr(scene.eom, "symmetric", True))


