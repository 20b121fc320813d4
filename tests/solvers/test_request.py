"""The records a run hands to the C boundary (lagcodegen.solvers.request): made from a family
object once, and written into a driver's options struct through the struct's declaration."""

import numpy as np
import pytest

from lagcodegen.codegen.signatures import CVC_OPTIONS, CVODE_OPTIONS, IDA_OPTIONS, TAYLOR_OPTIONS
from lagcodegen.solvers.cvode import CVODE
from lagcodegen.solvers.ida import IDA
from lagcodegen.solvers.request import (GGLForm, Index1Form, Recording, StepControl, option_fields,
                                        option_values)
from lagcodegen.solvers.taylor import Taylor


def test_step_control_of_a_family_takes_its_budgets_and_the_resolved_values():
    family = CVODE(max_steps=7, max_step=2, max_wall=1, first_step=1e-3, min_step=1e-9, max_order=3,
                   sensitivity_errcon=False, sensitivity_corrector="simultaneous")
    c = StepControl.of(family, 1e-6, 1e-8, method="bdf", jacobian=True)
    assert (c.rtol, c.atol, c.method, c.jacobian) == (1e-6, 1e-8, "bdf", True)
    assert (c.max_steps, c.first_step, c.max_step, c.min_step, c.max_order) == (7, 1e-3, 2.0, 1e-9, 3)
    assert type(c.max_step) is float and type(c.max_wall) is float and c.max_wall == 1.0
    assert (c.errcon, c.corrector, c.band, c.fixedpoint) == (False, "simultaneous", None, False)
    assert StepControl.of(Taylor(order=9), 1e-8, 1e-10, method="taylor").order == 9
    assert StepControl.of(IDA(), 1e-8, 1e-10).max_order == 0
    with pytest.raises(Exception):
        c.rtol = 1.0  # frozen


def test_option_fields_are_the_declared_fields_the_records_carry_in_struct_order():
    c = StepControl(rtol=1e-7, atol=1e-9, method="adams", max_steps=50, band=(2, 1), jacobian=True, order=None)
    for struct, form in ((CVODE_OPTIONS, None), (CVC_OPTIONS, Index1Form(1.5, 2.5, True, 1e-10, 4)),
                         (IDA_OPTIONS, GGLForm(False, True)), (TAYLOR_OPTIONS, None)):
        fields = option_fields(struct, c, form, Recording(roots=True))
        declared = [f.name for f in struct.fields]
        assert list(fields) == [n for n in declared if n in fields]
        assert not {"atol", "atol_vec", "poll", "poll_data", "poll_every", "cancel"} & set(fields)
    assert option_fields(CVODE_OPTIONS, c) == dict(
        method=1, jacobian=1, rtol=1e-7, max_steps=50, first_step=0.0, max_step=0.0, min_step=0.0, max_order=0,
        linear_solver=1, mupper=2, mlower=1, max_wall=0.0)
    cvc = option_fields(CVC_OPTIONS, c, Index1Form(1.5, 2.5, True, 1e-10, 4), Recording(roots=True))
    assert (cvc["alpha"], cvc["beta"], cvc["projection"], cvc["proj_tol"], cvc["proj_maxit"], cvc["roots"]) == \
        (1.5, 2.5, 1, 1e-10, 4, 1)
    ida = option_fields(IDA_OPTIONS, c, GGLForm(False, True), Recording(roots=False))
    assert (ida["suppress_alg"], ida["stop_at_outputs"], ida["roots"], ida["jacobian"]) == (0, 1, 0, 1)
    assert option_fields(TAYLOR_OPTIONS, c.replace(method="taylor", order=7))["order"] == 7
    assert option_fields(CVODE_OPTIONS, c.replace(band=None, fixedpoint=True))["linear_solver"] == 2
    assert option_values(CVODE_OPTIONS, ("rtol", "method", "mlower"), c) == (1e-7, 1, 1)


def test_an_ensembles_event_table_is_not_a_roots_flag():
    table = np.zeros(1)  # stands for the lcg_ode_roots pointer an ODE ensemble carries in roots
    assert "roots" not in option_fields(CVC_OPTIONS, StepControl(rtol=1e-8, atol=1e-10, method="bdf"),
                                        Index1Form(0.0, 0.0), Recording(roots=table))


def test_records_are_remembered_per_owner_while_the_key_stays_equal():
    from lagcodegen.solvers.request import remembered
    owner, made = CVODE(max_steps=11), []

    def make():
        made.append(1)
        return StepControl.of(owner, 1e-8, 1e-10, method="adams")

    first = remembered(owner, (1e-8, 1e-10), make)
    assert remembered(owner, (1e-8, 1e-10), make) is first and len(made) == 1
    assert remembered(owner, (1e-9, 1e-10), make) is not first and len(made) == 2
    assert remembered(CVODE(max_steps=11), (1e-9, 1e-10), make) is not first and len(made) == 3  # another owner
    remembered(owner, None, make)
    remembered(owner, None, make)
    assert len(made) == 5  # key None: made every time
