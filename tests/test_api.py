"""The one-call entry points of lagcodegen.api that the other tests do not already cover:
compile_urdf's cache of generated code (a new process compiling the same URDF derives nothing)."""

import numpy as np
import pytest

import lagcodegen as lcg
import lagcodegen.api as api
from lagcodegen import ModelError
from lagcodegen.codegen.record import stored_scene
from lagcodegen.modelfile import urdf

ARM = """<robot name="{name}"><link name="base"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="upper"><inertial><origin xyz="0 0 -0.25"/><mass value="{mass}"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="elbow" type="continuous"><parent link="upper"/><child link="fore"/><origin xyz="0 0 -0.5"/>
    <axis xyz="0 1 0"/></joint>
  <link name="fore"><inertial><origin xyz="0 0 -0.2"/><mass value="0.7"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""


def _refuse_derive(monkeypatch):
    def refuse(*_args, **_kwargs):
        raise AssertionError("derived although the code is in the cache")
    monkeypatch.setattr(api, "derive", refuse)


def test_compile_urdf_loads_the_code_from_the_cache_without_deriving(tmp_path, monkeypatch):
    path = tmp_path / "arm.urdf"
    path.write_text(ARM.format(name="cached_arm", mass=1.3))
    t = np.linspace(0.0, 1.0, 11)
    q0 = [0.4, -0.2]
    first = lcg.compile_urdf(path, outputs=["energy"])
    want = first.simulate(t, q0=q0)
    reference = lcg.compile_model(urdf.load(path), outputs=["energy"]).simulate(t, q0=q0)
    np.testing.assert_array_equal(want.y, reference.y)  # the same code as compile_model's
    with monkeypatch.context() as m:
        _refuse_derive(m)
        again = lcg.compile_urdf(path, outputs=["energy"])  # from the cache: nothing derived
        got = again.simulate(t, q0=q0)
        np.testing.assert_array_equal(got.y, want.y)
        np.testing.assert_array_equal(got.outputs["energy"], want.outputs["energy"])
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_urdf(path, outputs=[])  # other options: another entry, derived
        path.write_text(ARM.format(name="cached_arm", mass=1.4))
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_urdf(path, outputs=["energy"])  # another file: derived
    # what needs the symbolic scene derives it again from the file, once
    path.write_text(ARM.format(name="cached_arm", mass=1.3))
    again = lcg.compile_urdf(path, outputs=["energy"])
    assert stored_scene(again.code) is None and again.code.rederive is not None
    taylor = again.simulate(t, q0=q0, method="taylor", rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(taylor.y, first.simulate(t, q0=q0, method="taylor", rtol=1e-12, atol=1e-12).y,
                               rtol=0, atol=1e-13)
    drawing = got.drawing()  # the cached model's drawing: its scene derived on reading
    assert {"upper", "fore"} <= set(drawing.points)


def test_compile_urdf_with_limits_is_cached_by_the_file(tmp_path, monkeypatch):
    """limits=True: the URDF's stops as contacts on the impact driver, the same code as
    compile_constrained(urdf.load(path, limits=True)) gives (the same run to the bit), read from the
    cache the second time without deriving or generating; another restitution is another entry."""
    path = tmp_path / "arm.urdf"
    path.write_text(ARM.format(name="stopped_arm", mass=1.0))
    t = np.linspace(0.0, 1.5, 31)
    start = dict(q0=[2.6, 0.0], v0=[3.0, 0.0])  # swung at its upper stop (shoulder <= 3)
    first = lcg.compile_urdf(path, limits=True)
    assert isinstance(first, api.ConstrainedSimulation) and first.formulation == "index1"
    want = first.simulate(t, **start)
    reference = api.compile_constrained(urdf.load(path, limits=True)).simulate(t, **start)
    np.testing.assert_array_equal(want.y, reference.y)
    assert want.success and len(want.impacts.select(contact=1)) > 0  # the upper stop was hit
    assert want.y[:, 0].max() <= 3.0 + 1e-8
    with monkeypatch.context() as m:
        _refuse_derive(m)
        m.setattr(api, "generate_constrained", lambda *a, **k: pytest.fail("generated although cached"))
        again = lcg.compile_urdf(path, load={"limits": True})  # the same entry, from the cache
        got = again.simulate(t, **start)
        np.testing.assert_array_equal(got.y, want.y)
        assert [(r.t, r.kind) for r in got.impacts] == [(r.t, r.kind) for r in want.impacts]
        with pytest.raises(pytest.fail.Exception, match="generated although cached"):
            lcg.compile_urdf(path, limits=("stop", 0.5))  # another restitution: another entry
    assert stored_scene(again.compiled.code) is None and again.compiled.code.rederive is not None


def test_compile_urdf_refuses_what_it_cannot_cache(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(ARM.format(name="limited_arm", mass=1.0))
    with pytest.raises(ModelError, match="limits=True and load=.*disagree"):
        lcg.compile_urdf(path, limits=True, load={"limits": False})
    with pytest.raises(ModelError, match="constrained system.*native=True"):
        lcg.compile_urdf(path, limits=True, native=False)
    with pytest.raises(ModelError, match="missing.urdf.*cannot read the file"):
        lcg.compile_urdf(tmp_path / "missing.urdf")
