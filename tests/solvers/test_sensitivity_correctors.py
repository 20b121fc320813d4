"""The two correctors of the CVODE sensitivity driver (lcg_cvsens.c): staggered (the states'
Newton iteration first, then the sensitivities with the same matrix; the default) and
simultaneous (every direction in every iteration). They solve the same equations, so they agree
to the tolerance; both against central differences; the staggered one on every path that
shares the driver (BDF's scaled solves, the integrator object); a solver object of another
layout is an error with a message, not a crash."""

import numpy as np
import pytest

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError

NAMES = ["l2", "g", "theta1(0)", "theta2_dot(0)"]
Q0, V0 = [1.0, -0.5], [0.2, 0.1]


@pytest.fixture(scope="module")
def dp():
    return lcg.compile_model(lcg.systems.double_pendulum(), outputs=["energy"])


def _run(dp, t, corrector, **kw):
    kw = {"q0": Q0, "v0": V0, "rtol": 1e-10, "atol": 1e-12, "sensitivities": NAMES, **kw}
    res = dp.simulate(t, sensitivity_corrector=corrector, **kw)
    assert res.status == 0, res.message
    return res


def _central(dp, t, name, h=2e-4):
    """Fourth-order central differences of the states along ``name`` (rtol 1e-13 runs)."""
    base = dict(zip(dp.param_names, dp.parameter_vector()))
    runs = {}
    for k in (2, 1, -1, -2):
        q0, v0, params = list(Q0), list(V0), dict(base)
        if name.endswith("_dot(0)"):
            i = dp.state_names.index(name[:-7])
            v0[i] += k * h
        elif name.endswith("(0)"):
            i = dp.state_names.index(name[:-3])
            q0[i] += k * h
        else:
            params[name] *= 1 + k * h
        runs[k] = dp.simulate(t, q0=q0, v0=v0, params=params, rtol=1e-13, atol=1e-15).y
    step = h if name.endswith("(0)") else h * base[name]
    return (8 * (runs[1] - runs[-1]) - (runs[2] - runs[-2])) / (12 * step)


@pytest.mark.parametrize("method", ["adams", "bdf"])
def test_staggered_and_simultaneous_agree(dp, method):
    """The same sensitivities (and states, outputs' sensitivities) from both correctors, Adams and
    BDF (whose solves the staggered corrector scales for the gamma of the step, as CVODE does);
    the staggered one evaluates the states alone in its Newton iterations and each direction
    about once per step, the simultaneous one every direction at every iteration."""
    t = np.linspace(0.0, 3.0, 31)
    a = _run(dp, t, "staggered", method=method)
    b = _run(dp, t, "simultaneous", method=method)
    scale = np.max(np.abs(b.sensitivities), axis=(0, 2))
    for j in range(len(NAMES)):
        assert np.max(np.abs(a.sensitivities[:, j] - b.sensitivities[:, j])) < 1e-6 * scale[j], NAMES[j]
    assert np.max(np.abs(a.y - b.y)) < 1e-7
    sa, sb = a.stats, b.stats
    assert sa["rhs_evals_states"] >= sa["steps"] and sb["rhs_evals_states"] == 0
    assert sa["steps"] <= sa["sens_iters"] < 2 * sa["steps"] and sb["sens_iters"] == 0
    # each sensitivity evaluation solves every block once (plus the states' solves)
    assert sa["block_solves"] >= len(NAMES) * sa["sens_iters"] + sa["nonlin_iters"]


@pytest.mark.parametrize("corrector", ["staggered", "simultaneous"])
def test_correctors_against_central_differences(dp, corrector):
    """Both correctors: the states' sensitivities within relative 1e-6 at rtol 1e-8 of central
    differences (with the sensitivities in the error test, the default)."""
    t = np.linspace(0.0, 3.0, 16)
    res = _run(dp, t, corrector, rtol=1e-8, atol=1e-10)
    for j, name in enumerate(NAMES):
        ref = _central(dp, t, name)
        err = np.max(np.abs(res.sensitivities[:, j, :4] - ref)) / np.max(np.abs(ref))
        assert err < 1e-6, (corrector, name, err)


def test_integrator_object_uses_the_chosen_corrector(dp):
    """The integrator object (lcg_cvsens_stepper.c) runs the same corrector as simulate(): a fresh
    integrator's grid equals the run's, for each corrector."""
    t = np.linspace(0.0, 1.0, 11)
    for corrector in ("staggered", "simultaneous"):
        ref = _run(dp, t, corrector)
        integ = dp.integrator(q0=Q0, v0=V0, rtol=1e-10, atol=1e-12, sensitivities=NAMES,
                              sensitivity_corrector=corrector)
        y, S = integ.propagate_grid(t)
        assert np.array_equal(y, ref.y), corrector
        assert np.array_equal(S, ref.sensitivities[:, :, :4].transpose(0, 2, 1)), corrector


def test_unknown_corrector_is_named(dp):
    with pytest.raises(LagcodegenError, match="sensitivity_corrector"):
        dp.simulate([0.0, 1.0], q0=Q0, sensitivities=NAMES, sensitivity_corrector="newton")


HARNESS_H = "int lcg_test_nls_object_layout(char *message, int size);\n"
HARNESS_C = r"""
#include "lcg_cvsens.c"
#include "harness.h"

/* A solver object of SUNDIALS 7.5's layout (content, ops, sunctx: no reserved slot) handed to
 * the staggered corrector's check; the extra slot keeps the check's read inside the object. */
int lcg_test_nls_object_layout(char *message, int size)
{
    SUNContext ctx = NULL;
    void *slots[4] = {NULL, NULL, NULL, NULL};
    void *ops[15] = {NULL};
    sens_data d;
    int flag;

    memset(&d, 0, sizeof d);
    if (SUNContext_Create(0, &ctx) != 0)
        return 1;
    slots[1] = ops;
    slots[2] = ctx;
    message[0] = '\0';
    flag = nls_attach((SUNNonlinearSolver)(void *)slots, ctx, &d, message, (size_t)size);
    SUNContext_Free(&ctx);
    return flag;
}
"""


def test_solver_object_of_another_layout_is_an_error():
    """The staggered corrector checks the SUNNonlinearSolver's layout before use: an object of
    another SUNDIALS version's layout is refused with LCG_FLAG_BAD_INPUT and a message."""
    from lagcodegen.build import driver_runtime, find_sundials
    from lagcodegen.solvers.cvode.sensitivity import LINKED_UNITS, _sources
    sundials = find_sundials()

    def render():
        return {**_sources(), "harness.c": HARNESS_C, "harness.h": HARNESS_H}

    rt = driver_runtime("cvsens_layout_test", [HARNESS_C, *(f"{k}\0{v}" for k, v in sorted(_sources().items()))],
                        render, HARNESS_H, "harness.h", [*sundials.link_args(("cvode", "core")), "-lm"],
                        units=("harness.c", *LINKED_UNITS))
    msg = rt.ffi.new("char[]", 256)
    flag = rt.lib.lcg_test_nls_object_layout(msg, 256)
    text = rt.ffi.string(msg).decode()
    assert flag == -22, (flag, text)
    assert "nonlinear solver object has another layout" in text
