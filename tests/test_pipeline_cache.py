"""The pipeline cache (issue 38): compile_file (TOML model files, constrained ones too) and
compile_model (a Model by its canonical form) keep their generated code in the cache, so that a
new process loads a compiled model without deriving or generating it, bit for bit the model a
fresh build gives; any change of the model misses, a damaged entry is rebuilt, a model without a
canonical form is never cached; a build that really runs is a progress stage."""

import os
import subprocess
import sys
import uuid
import warnings

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
import lagcodegen.api as api
from lagcodegen.cache import CacheWarning, cache_dir
from lagcodegen.codegen.record import CachedCode, stored_scene
from lagcodegen.model.bodies import Joint, Placement
from lagcodegen.model.canonical import canonical_form, why_not_canonical
from lagcodegen.modelfile import document

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
T = np.linspace(0.0, 1.0, 11)

PENDULUM = """[model]
name = "{name}"
coordinates = ["theta1", "theta2"]

[parameters]
l1 = 1.0
l2 = {l2}
m1 = 1.0
m2 = 1.0
g = 9.81

[[particles]]
name = "bob1"
mass = "m1"
position = ["l1*sin(theta1)", "-l1*cos(theta1)"]

[[particles]]
name = "bob2"
mass = "m2"
position = ["l1*sin(theta1) + l2*sin(theta2)", "-l1*cos(theta1) - l2*cos(theta2)"]

[gravity]
g = "g"

[simulation]
initial = {{ theta1 = 1.0, theta2 = 0.5 }}
outputs = ["energy"]
"""

#: Run in a new process: derivation refused, the model compiled, its run saved for comparison.
CHILD = r"""
import sys
import numpy as np
import lagcodegen as lcg
import lagcodegen.api as api
from lagcodegen.modelfile import document
from lagcodegen.codegen.record import stored_scene

def refuse(*_args, **_kwargs):
    raise SystemExit("derived although the model is in the cache")

api.derive = document.derive = refuse
api.generate_code = api.generate_constrained = refuse
kind, source, out = sys.argv[1:4]
stages = []
if kind == "file":
    sim = lcg.compile_file(source, progress=lambda *a: stages.append(a[0]))
    res = sim.simulate(np.linspace(0.0, 1.0, 11))
else:
    namespace = {}
    exec(source, namespace)
    sim = lcg.compile_model(namespace["model"], outputs=["energy"], progress=lambda *a: stages.append(a[0]))
    res = sim.simulate(np.linspace(0.0, 1.0, 11), q0=[0.3, -0.2])
code = getattr(sim, "compiled", sim).code
assert stored_scene(code) is None and not stages, (stages, type(code))
np.save(out, res.y)
"""

#: A tree model (links, joints, a placement) and point masses, built the same way in both processes.
MODEL = """
import sympy as sp
from lagcodegen import Model
from lagcodegen.model.bodies import Joint, Placement
model = Model("canon_arm_{tag}")
m1, l = model.parameters(m1=1.25, l=0.5)
model.link("upper", joint=Joint.revolute("a", (0, 1, 0)), mass=m1, com=(0, 0, -l), inertia=(0.02, 0.02, 0.001))
model.link("fore", parent="upper", joint=Joint.revolute("b", (0, 1, 0)), origin=Placement(xyz=(0, 0, -2 * l)),
           mass=0.7, com=(0, 0, -0.2), inertia=(0.01, 0.01, 0.001))
model.gravity(9.81, up=(0, 0, 1))
"""


def _child(kind: str, source: str, out) -> np.ndarray:
    env = {**os.environ, "PYTHONPATH": ROOT, "PYTHONHASHSEED": "12345"}
    proc = subprocess.run([sys.executable, "-c", CHILD, kind, source, str(out)], capture_output=True, text=True,
                          env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return np.load(out)


def _keys(monkeypatch) -> list:
    """The pipeline cache's keys used from now on, in order."""
    keys = []
    real = api.cached_code

    def spy(key, *args, **kwargs):
        keys.append(key)
        return real(key, *args, **kwargs)

    monkeypatch.setattr(api, "cached_code", spy)
    return keys


def _refusing(monkeypatch):
    def refuse(*_args, **_kwargs):
        raise AssertionError("derived although the model is in the cache")
    monkeypatch.setattr(api, "derive", refuse)
    monkeypatch.setattr(document, "derive", refuse)


def test_a_model_file_loads_in_a_new_process_without_deriving_and_any_edit_misses(tmp_path, monkeypatch):
    name = f"cached_file_{uuid.uuid4().hex[:8]}"
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM.format(name=name, l2="1.0"))
    stages = []
    fresh = lcg.compile_file(path, progress=lambda *a: stages.append(a[0]))
    assert stages[0] == "build" and "derive" in stages  # a build that really runs says so
    want = fresh.simulate(T)
    np.testing.assert_array_equal(_child("file", str(path), tmp_path / "y.npy"), want.y)  # bit for bit
    with monkeypatch.context() as m:
        _refusing(m)
        again = lcg.compile_file(path)  # this process too: from the cache
        assert isinstance(again.code, CachedCode) and stored_scene(again.code) is None
        np.testing.assert_array_equal(again.simulate(T).y, want.y)
        path.write_text(PENDULUM.format(name=name, l2="1.5"))  # one character of the file
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_file(path)
        path.write_text(PENDULUM.format(name=name, l2="1.0").replace('"m2"', '"m1"'))  # an expression
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_file(path)
        path.write_text("# a comment changes no model\n" + PENDULUM.format(name=name, l2="1.0").replace(
            "[simulation]", "[simulation]\nt_end = 3.0"))  # nor do the integration's settings
        np.testing.assert_array_equal(lcg.compile_file(path).simulate(T).y, want.y)  # the same model: a hit
        path.write_text(PENDULUM.format(name=name, l2="1.0"))
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_file(path, outputs=[])  # other options: another entry
    # what needs the scene derives it again, once: the Taylor method on the cached model
    again = lcg.compile_file(path)
    taylor = again.simulate(T, method="taylor", rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(taylor.y, fresh.simulate(T, method="taylor", rtol=1e-12, atol=1e-12).y,
                               rtol=0, atol=1e-12)


def test_a_constrained_model_file_loads_in_a_new_process_without_deriving(tmp_path, monkeypatch):
    text = open(os.path.join(ROOT, "examples", "cartesian_pendulum.toml")).read()
    path = tmp_path / "cartesian.toml"
    name = f"cached_cartesian_{uuid.uuid4().hex[:8]}"
    path.write_text(text.replace('name = "cartesian_pendulum"', f'name = "{name}"'))
    fresh = lcg.compile_file(path)
    assert isinstance(fresh, api.ConstrainedSimulation)
    want = fresh.simulate(T)
    np.testing.assert_array_equal(_child("file", str(path), tmp_path / "y.npy"), want.y)
    with monkeypatch.context() as m:
        _refusing(m)
        m.setattr(api, "generate_constrained", lambda *a, **k: pytest.fail("generated although cached"))
        again = lcg.compile_file(path)
        assert stored_scene(again.compiled.code) is None
        np.testing.assert_array_equal(again.simulate(T).y, want.y)
        np.testing.assert_array_equal(again.simulate(T).outputs["lambda_0"], want.outputs["lambda_0"])
        stiffer = lcg.compile_file(path, baumgarte=(3.0, 3.0))  # a run-time option: the same code
        assert stiffer.simulate(T).success
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_file(path, outputs=["energy"])  # other outputs: another entry, derived


def test_a_model_loads_in_a_new_process_without_deriving(tmp_path, monkeypatch):
    source = MODEL.format(tag=uuid.uuid4().hex[:8])
    namespace: dict = {}
    exec(source, namespace)
    stages = []
    fresh = lcg.compile_model(namespace["model"], outputs=["energy"], progress=lambda *a: stages.append(a[0]))
    assert stages[0] == "build"
    want = fresh.simulate(T, q0=[0.3, -0.2])
    np.testing.assert_array_equal(_child("model", source, tmp_path / "y.npy"), want.y)
    with monkeypatch.context() as m:
        _refusing(m)
        rebuilt: dict = {}
        exec(source, rebuilt)  # the same statements again: the same canonical form
        np.testing.assert_array_equal(lcg.compile_model(rebuilt["model"], outputs=["energy"]).simulate(
            T, q0=[0.3, -0.2]).y, want.y)
        model = rebuilt["model"]
        model.params[next(iter(model.params))] = 1.5  # a parameter's default changed in place
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_model(model, outputs=["energy"])
        model.params[next(iter(model.params))] = 1.25
        model.links[1].mass = sp.Float(0.75)  # a link's mass changed in place
        with pytest.raises(AssertionError, match="derived although"):
            lcg.compile_model(model, outputs=["energy"])


CONCURRENT = r"""
import sys
import numpy as np
import lagcodegen as lcg
sim = lcg.compile_file(sys.argv[1])
np.save(sys.argv[2], sim.simulate(np.linspace(0.0, 1.0, 11)).y)
"""


def test_processes_building_one_model_at_once_all_succeed(tmp_path, monkeypatch):
    """Three new processes compile one new model file at the same time: each succeeds (one
    publishes the entry, the others' builds lose the race harmlessly), with the same results, and
    the entry is then used without deriving."""
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM.format(name=f"concurrent_{uuid.uuid4().hex[:8]}", l2="1.0"))
    env = {**os.environ, "PYTHONPATH": ROOT}
    procs = [subprocess.Popen([sys.executable, "-c", CONCURRENT, str(path), str(tmp_path / f"y{i}.npy")],
                              env=env, stderr=subprocess.PIPE, text=True) for i in range(3)]
    for p in procs:
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-3000:]
    ys = [np.load(tmp_path / f"y{i}.npy") for i in range(3)]
    for y in ys[1:]:
        np.testing.assert_array_equal(y, ys[0])
    assert not [p for p in cache_dir().iterdir() if p.name.startswith(".build-")
                and str(os.getpid()) not in p.name and any(str(q.pid) in p.name for q in procs)]
    with monkeypatch.context() as m:
        _refusing(m)
        np.testing.assert_array_equal(lcg.compile_file(path).simulate(T).y, ys[0])


def _arm(mass=1.25, axis=(0, 1, 0), coordinate="a", com="-l", name="canon_arm", origin=(0, 0, -1.0)):
    namespace: dict = {}
    exec(MODEL.format(tag="x").replace("canon_arm_x", name).replace("1.25", repr(mass))
         .replace('Joint.revolute("a", (0, 1, 0))', f'Joint.revolute("{coordinate}", {axis!r})')
         .replace("com=(0, 0, -l)", f"com=(0, 0, {com})").replace("xyz=(0, 0, -2 * l)", f"xyz={origin!r}"),
         namespace)
    return namespace["model"]


def test_every_edit_of_a_model_changes_its_canonical_form_and_the_form_is_the_same_in_every_process():
    base = canonical_form(_arm())
    assert base is not None and base == canonical_form(_arm())
    edits = [_arm(mass=1.26), _arm(axis=(1, 0, 0)), _arm(coordinate="alpha"), _arm(com="-l/2"), _arm(name="other"),
             _arm(origin=(0, 0, -1.0 + 1e-15)), _arm(axis=(0, -1, 0))]
    forms = [canonical_form(m) for m in edits]
    assert None not in forms and len(set(forms + [base])) == len(edits) + 1
    model = _arm()
    model.potential_energy(sp.Symbol("theta_extra", real=True) * 0 + 1, label="V0")  # a term added later
    assert canonical_form(model) != base
    # assumptions of a symbol and a float's last bit are the model's too
    a, b = lcg.Model("p"), lcg.Model("p")
    x, = a.coordinates("x")
    y, = b.coordinates("x")
    a.potential_energy(0.1 * x**2)
    b.potential_energy(0.30000000000000004 / 3 * y**2)
    assert (canonical_form(a) == canonical_form(b)) == (0.1 == 0.30000000000000004 / 3)
    # the same text in a new process, whatever its hash seed
    script = ("import hashlib, sys; sys.path.insert(0, %r); from tests.test_pipeline_cache import _arm; "
              "from lagcodegen.model.canonical import canonical_form; "
              "print(hashlib.sha256(canonical_form(_arm()).encode()).hexdigest())" % ROOT)
    import hashlib
    for seed in ("1", "2"):
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                             env={**os.environ, "PYTHONPATH": ROOT, "PYTHONHASHSEED": seed})
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.strip() == hashlib.sha256(base.encode()).hexdigest()


def test_a_model_without_a_canonical_form_is_never_cached(monkeypatch):
    """A sympy function implemented in Python, a Function subclass of the user's: the model is
    derived every time (never a wrong hit) and still compiles."""
    from sympy.utilities.lambdify import implemented_function

    class wobble(sp.Function):  # noqa: N801 - a sympy function class of the user's
        @classmethod
        def eval(cls, x):
            return None

    class Derived(Exception):
        pass

    for f in (implemented_function("soft", lambda x: x), wobble):
        m = lcg.Model(f"uncanonical_{uuid.uuid4().hex[:6]}")
        q, = m.coordinates("q")
        m.kinetic_energy(m.dot(q) ** 2 / 2)
        m.potential_energy(q**2 / 2)
        m.output("w", f(q))
        assert canonical_form(m) is None and why_not_canonical(m)
        keys = _keys(monkeypatch)
        monkeypatch.setattr(api, "derive", lambda model: (_ for _ in ()).throw(Derived()))
        with pytest.raises(Derived):
            lcg.compile_model(m, outputs=["w"])  # derived at once: no cache entry asked for
        assert keys == []
        monkeypatch.undo()
    plain = lcg.Model("plain")
    q, = plain.coordinates("q")
    plain.potential_energy(q**2)
    keys = _keys(monkeypatch)
    monkeypatch.setattr(api, "derive", lambda model: (_ for _ in ()).throw(Derived()))
    with pytest.raises(Derived):
        lcg.compile_model(plain, prefix=f"plain_{uuid.uuid4().hex[:8]}")
    assert len(keys) == 1  # a model with a canonical form is looked up in the cache first
    assert canonical_form(object()) is None and "object" in why_not_canonical([1, object()])


@pytest.mark.parametrize("damage", ["truncated", "rewritten with its digest"])
def test_a_damaged_entry_is_rebuilt_never_trusted(tmp_path, monkeypatch, damage):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM.format(name=f"damaged_{uuid.uuid4().hex[:8]}", l2="1.0"))
    keys = _keys(monkeypatch)
    want = lcg.compile_file(path).simulate(T)
    entry = cache_dir() / keys[-1]
    data = (entry / "code.pickle").read_bytes()
    os.chmod(entry / "code.pickle", 0o600)
    if damage == "truncated":
        (entry / "code.pickle").write_bytes(data[: len(data) // 2])
    else:  # a consistent entry whose record is not a pickle: refused when it does not load
        import hashlib
        (entry / "code.pickle").write_bytes(b"not a pickle" + data[:10])
        os.chmod(entry / "module.sha256", 0o600)
        (entry / "module.sha256").write_text(
            f"{hashlib.sha256((entry / 'code.pickle').read_bytes()).hexdigest()}  code.pickle\n")
    calls = []
    real = document.derive
    monkeypatch.setattr(document, "derive", lambda model: calls.append(1) or real(model))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rebuilt = lcg.compile_file(path)
    assert calls == [1]  # derived again
    assert any(issubclass(w.category, CacheWarning) and "rebuilding" in str(w.message) for w in caught)
    np.testing.assert_array_equal(rebuilt.simulate(T).y, want.y)
    assert (entry / "code.pickle").read_bytes() != data[: len(data) // 2]  # replaced by a sound entry
    calls.clear()
    lcg.compile_file(path)
    assert calls == []  # and that one is used


def test_placements_and_joints_are_in_the_form():
    assert canonical_form(Placement(xyz=(0, 0, 1))) != canonical_form(Placement(xyz=(0, 0, 1), rpy=(0, 0, 0.1)))
    assert canonical_form(Joint.revolute("a", (0, 0, 1))) != canonical_form(Joint.prismatic("a", (0, 0, 1)))
