"""Ensembles with the Taylor method (``method="taylor"``): the Taylor integrator of the scene
(:mod:`.taylor`, ``<prefix>_taylor_solve``) plus ``<prefix>_taylor_ens.c``
(templates/taylor/ensemble.c.j2), built once per compiled model. The Taylor driver has no run
control of its own, so Ctrl-C takes effect between members and ``max_wall`` is not available."""

from __future__ import annotations

import numpy as np

from ...build import build
from ...codegen.cffi_decl import POLL_CDEF, ensemble_cdef
from ...codegen.templates import environment
from ...version import __version__
from .. import control
from ..base import tolerances
from ..ensemble_run import run_native
from .run import scene_of
from .runner import taylor_code


def taylor_ensemble_module(cm):
    """The compiled Taylor integrator of ``cm``'s scene with its ensemble driver (built once)."""
    key = ("taylor-ensemble",)
    module = cm.solver_state.get(key)
    if module is None:
        code, _, _ = taylor_code(scene_of(cm))
        pre = code.prefix
        ctx = dict(prefix=pre, PREFIX=pre.upper(), version=__version__)
        env = environment()
        code.files[f"{pre}_taylor_ens.h"] = env.get_template("taylor/ensemble.h.j2").render(**ctx)
        code.files[f"{pre}_taylor_ens.c"] = env.get_template("taylor/ensemble.c.j2").render(**ctx)
        code.cffi_headers.append(f"{pre}_taylor_ens.h")
        code.cdef_extra += "\n" + ensemble_cdef(f"{pre}_taylor_ensemble", f"{pre}_taylor_options",
                                                f"{pre}_taylor_solve_many") + "\n" + POLL_CDEF
        module = cm.solver_state[key] = build(code, native=False).module
    return module


def run_taylor_ensemble(cm, t, Y, P, *, threads, save, progress, rtol=1e-8, atol=1e-10, max_step=0.0,
                        max_steps=1_000_000, order=None, method="taylor", **ignored):
    module = taylor_ensemble_module(cm)
    ffi, lib, pre = module.ffi, module.lib, cm.code.prefix
    rtol, atol_arr = tolerances(rtol, atol, cm.ny)
    opt = ffi.new(f"{pre}_taylor_options *")
    opt.rtol = rtol
    keep = []
    if np.all(atol_arr == atol_arr[0]):
        opt.atol = float(atol_arr[0])
        opt.atol_vec = ffi.NULL
    else:
        keep.append(atol_arr)
        opt.atol = float(atol_arr.min())
        opt.atol_vec = ffi.from_buffer("double[]", atol_arr)
    opt.max_steps = int(max_steps)
    opt.max_step = float(max_step)
    opt.order = int(order or 0)
    return run_native(ffi, getattr(lib, f"{pre}_taylor_solve_many"), f"{pre}_taylor_ensemble", opt, t=t, Y0=Y, P=P,
                      nrow=cm.ny, nout=cm.code.nout, state_names=cm.state_names, output_names=cm.output_names,
                      row_names=cm.state_names, save=save, threads=threads, progress=progress,
                      poll=control.install(module), method="taylor", n_coordinates=cm.n,
                      param_names=cm.param_names)
