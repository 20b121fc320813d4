"""Animations drawn from the model's own points (lagcodegen.animation, formulation.drawing):
links read from the geometry, positions from the outputs or computed from the states, GIF
frames whose pixels sit where the trajectory says, 3-D models, the HTML player written
atomically, and clear errors where nothing can be drawn."""

import pickle

import numpy as np
import pytest
import sympy as sp
from matplotlib.colors import to_rgb
from PIL import Image

import lagcodegen as lcg
from lagcodegen.animation import Animator, Drawing, ffmpeg_available, frame_times
from lagcodegen.errors import LagcodegenError
from lagcodegen.formulation.drawing import drawing_of
from lagcodegen.result import Result

T = np.linspace(0.0, 2.0, 41)


@pytest.fixture(scope="module")
def dp_runs():
    """The double pendulum without and with the positions outputs (the C code's own positions)."""
    model = lcg.systems.double_pendulum()
    plain = lcg.compile_model(model).simulate(T, q0=[1.2, -0.4], v0=[0.0, 1.0], rtol=1e-10, atol=1e-12)
    with_pos = lcg.compile_model(model, outputs=["positions", "energy"]).simulate(
        T, q0=[1.2, -0.4], v0=[0.0, 1.0], rtol=1e-10, atol=1e-12)
    return plain, with_pos


def test_links_are_read_from_the_geometry():
    d = drawing_of(lcg.Scene(lcg.derive(lcg.systems.double_pendulum())))
    assert d.points == {"bob1": 2, "bob2": 2} and d.dim == 2
    assert sorted(d.links) == [("bob1", "bob2"), ("origin", "bob1")]  # rods: suspension-bob1-bob2
    assert d.pivots == {"origin": (0.0, 0.0)} and d.fixed == ()
    orbit = drawing_of(lcg.Scene(lcg.derive(lcg.systems.central_potential())))
    assert orbit.links == [] and orbit.pivots == {}  # r varies: nothing holds the body
    sph = drawing_of(lcg.Scene(lcg.derive(lcg.systems.spherical_pendulum())))
    assert sph.dim == 3 and sph.links == [("origin", "bob")]
    # a declared anchor that never moves is drawn fixed and linked by the pair test, not the origin's
    m = lcg.Model("anchored")
    th, = m.coordinates("theta")
    m.point("anchor", (0, 0))
    m.particle("bob", 1, (2 * sp.sin(th), -2 * sp.cos(th)))
    a = drawing_of(lcg.Scene(lcg.derive(m)))
    assert a.fixed == ("anchor",) and a.links == [("anchor", "bob")] and a.pivots == {}


def test_positions_computed_from_the_states_equal_the_generated_outputs(dp_runs):
    plain, with_pos = dp_runs
    assert "bob2_x" not in plain.outputs and plain.model_name == "double_pendulum"
    computed = plain.tracks()
    emitted = with_pos.tracks()
    for p in ("bob1", "bob2"):
        assert np.allclose(computed[p], emitted[p], rtol=0, atol=1e-12)
    th1, th2 = plain["theta1"], plain["theta2"]
    assert np.allclose(computed["bob2"][:, 0], np.sin(th1) + np.sin(th2), atol=1e-12)
    assert np.allclose(computed["bob2"][:, 1], -np.cos(th1) - np.cos(th2), atol=1e-12)
    # run-time parameters in effect: a longer second rod moves the drawn bob
    longer = lcg.compile_model(lcg.systems.double_pendulum()).simulate(T, q0=[1.2, -0.4], params={"l2": 2.0})
    tr = longer.tracks()["bob2"]
    assert np.allclose(np.hypot(*(tr - longer.tracks()["bob1"]).T), 2.0, atol=1e-12)


def test_double_pendulum_gif_frames_show_the_trajectory(dp_runs, tmp_path):
    res = dp_runs[0]
    path = res.animate(tmp_path / "dp.gif", frames=len(T), fps=20)
    assert path == tmp_path / "dp.gif" and [p.name for p in tmp_path.iterdir()] == ["dp.gif"]
    gif = Image.open(path)
    assert gif.n_frames == len(T)
    # the same figure the writer drew: frame k's artists hold the positions at T[k]
    drawing, tracks = res.drawn(), res.tracks()
    anim = Animator(drawing, res.t, tracks, frame_times(res.t, fps=20, duration=None, frames=len(T)),
                    title=res.title())
    assert np.allclose(anim.times, T)
    bob_colour = 255 * np.array(to_rgb(anim.points["bob2"].get_color()))
    for k in (0, len(T) - 1):
        artists = anim.draw(k)
        assert np.array_equal(anim.data(anim.points["bob2"]), tracks["bob2"][k][None, :])
        assert np.array_equal(anim.data(anim.links[("bob1", "bob2")]), np.vstack([tracks["bob1"][k], tracks["bob2"][k]]))
        assert np.array_equal(anim.data(anim.links[("origin", "bob1")]), np.vstack([[0.0, 0.0], tracks["bob1"][k]]))
        assert anim.clock in artists
        gif.seek(k)
        frame = np.asarray(gif.convert("RGB"), dtype=float)
        col, row = anim.pixel(tracks["bob2"][k])
        r, c = int(round(row)), int(round(col))
        patch = frame[r - 2:r + 3, c - 2:c + 3].reshape(-1, 3)
        assert np.abs(patch - bob_colour).max(axis=1).min() < 40, (k, patch.mean(axis=0), bob_colour)
        # and the bob is not where the trajectory is not: the mirrored position is background
        mc, mr = anim.pixel(-tracks["bob2"][k])
        far = frame[int(round(mr)), int(round(mc))]
        assert np.abs(far - bob_colour).max() > 60


def test_spherical_pendulum_animates_in_3d(tmp_path):
    sim = lcg.compile_model(lcg.systems.spherical_pendulum())
    res = sim.simulate(np.linspace(0, 3, 61), q0=[1.0, 0.0], v0=[0.0, 2.0])
    path = res.animate(tmp_path / "sph.gif", frames=12, trail=True)
    assert Image.open(path).n_frames == 12
    tracks = res.tracks()
    assert tracks["bob"].shape == (61, 3)
    assert np.allclose(np.linalg.norm(tracks["bob"], axis=1), 1.0, atol=1e-12)  # l = 1
    anim = Animator(res.drawn(), res.t, tracks, res.t[::5], trail=True)
    anim.draw(3)
    assert np.array_equal(anim.data(anim.points["bob"]), tracks["bob"][15][None, :])
    assert anim.data(anim.trails["bob"]).shape == (17, 3)  # the whole path up to t[15], then the bob
    assert anim.ax.name == "3d"


def test_html_player_is_written_atomically(dp_runs, tmp_path, monkeypatch):
    res = dp_runs[1]
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    target = tmp_path / "dp.html"
    target.write_text("old")
    assert res.animate(target, frames=6) == target
    text = target.read_text()
    assert text.count("data:image/png;base64") == 6 and "<script" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dp.html", "victim.txt"]
    assert victim.read_text() == "precious\n"
    # a failure while drawing leaves the old file and no temporary
    from lagcodegen import animation

    def fail(self, k):
        raise OSError("disk full")
    monkeypatch.setattr(animation.Animator, "render", fail)
    with pytest.raises(OSError, match="disk full"):
        res.animate(target, frames=6)
    assert target.read_text() == text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dp.html", "victim.txt"]


def test_mp4_needs_ffmpeg(dp_runs, tmp_path):
    if ffmpeg_available():
        path = dp_runs[0].animate(tmp_path / "dp.mp4", frames=10)
        assert path.stat().st_size > 0
    else:
        with pytest.raises(LagcodegenError, match="ffmpeg"):
            dp_runs[0].animate(tmp_path / "dp.mp4", frames=10)
        assert not list(tmp_path.iterdir())


def test_frame_options_and_errors(dp_runs, tmp_path):
    res = dp_runs[0]
    assert len(frame_times(res.t, fps=10, duration=3.0, frames=None)) == 30
    assert len(frame_times(res.t, fps=25, duration=None, frames=None)) == 50  # 2 s run in real time
    for bad in ({"fps": 0}, {"frames": 0}, {"duration": -1.0}, {"frames": 10 ** 6}, {"trail": "yes"}):
        with pytest.raises(LagcodegenError):
            res.animate(tmp_path / "x.gif", **bad)
    with pytest.raises(LagcodegenError, match=r"\.gif, \.mp4, \.html"):
        res.animate(tmp_path / "x.avi")
    with pytest.raises(LagcodegenError, match="does not exist"):
        res.animate(tmp_path / "nowhere" / "x.gif")
    assert not list(tmp_path.iterdir())


def test_results_without_a_model_draw_their_position_outputs_or_say_what_to_request(tmp_path):
    t = np.linspace(0, 1, 11)
    y = np.column_stack([t, np.ones_like(t)])
    bare = Result(t=t, y=y, state_names=["x", "x_dot"], outputs={"energy": np.ones_like(t)}, n_coordinates=1)
    with pytest.raises(LagcodegenError, match=r"outputs=\['positions'\]"):
        bare.animate(tmp_path / "x.gif")
    located = Result(t=t, y=y, state_names=["x", "x_dot"], n_coordinates=1,
                     outputs={"cart_x": t, "cart_y": 0 * t, "tip_x": t + 0.5, "tip_y": -np.ones_like(t)})
    d = located.drawn()
    assert d.points == {"cart": 2, "tip": 2} and d.links == []
    assert Image.open(located.animate(tmp_path / "c.gif", frames=4)).n_frames == 4
    # a deferred drawing pickles as its record (no position function): positions must then be outputs
    res = lcg.compile_model(lcg.systems.pendulum()).simulate([0, 1], q0=[0.5])
    back = pickle.loads(pickle.dumps(res))
    assert isinstance(back.drawing, Drawing) and back.drawing.links == [("origin", "bob")]
    with pytest.raises(LagcodegenError, match="positions"):
        back.tracks()
    assert np.allclose(res.tracks()["bob"][:, 0], np.sin(res["theta"]), atol=1e-12)


def heavy_top():
    """A symmetric top on a fixed tip: Euler angles (z-x-z), centre of mass l along the body's z axis."""
    m = lcg.Model("top")
    phi, theta, psi = m.coordinates("phi theta psi")
    mass, l, g, I1, I3 = m.parameters(m=1.0, l=0.5, g=9.81, I1=0.3, I3=0.1)

    def rz(a):
        return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])

    R = rz(phi) * sp.Matrix([[1, 0, 0], [0, sp.cos(theta), -sp.sin(theta)], [0, sp.sin(theta), sp.cos(theta)]]) \
        * rz(psi)
    m.rigid_body("top", mass, [I1, I1, I3], R * sp.Matrix([0, 0, l]), R)
    m.gravity(g)
    return m


def test_a_spinning_top_draws_its_body_axes(tmp_path):
    res = lcg.compile_model(heavy_top()).simulate(np.linspace(0, 1, 51), q0=[0.0, 0.5, 0.0], v0=[1.0, 0.0, 30.0])
    d = res.drawn()
    assert d.links == [("origin", "top")] and d.dim == 3
    assert d.body_axes == {"top.x": ("top", "x"), "top.y": ("top", "y"), "top.z": ("top", "z")}
    tr = res.tracks()
    c = tr["top"]
    assert np.allclose(np.linalg.norm(c, axis=1), 0.5, atol=1e-12)  # the tip is fixed: |x_G| = l
    arms = {a: tr[f"top.{a}"] - c for a in "xyz"}
    length = np.linalg.norm(arms["x"], axis=1)
    assert np.allclose(length, 0.3 * 0.5, rtol=1e-9)  # AXIS_FRACTION of the model's reach
    for a, b in (("x", "y"), ("y", "z"), ("x", "z")):
        assert np.allclose(np.einsum("ij,ij->i", arms[a], arms[b]), 0, atol=1e-12)  # body axes stay orthogonal
    assert np.allclose(np.cross(arms["z"], c), 0, atol=1e-12)  # the symmetry axis points at the centre
    # the spin turns the x axis about the symmetry axis: about 30 rad/s, so it moves between frames
    assert np.linalg.norm(arms["x"][1] - arms["x"][0]) > 0.1 * length[0]
    anim = Animator(d, res.t, tr, res.t[:3])
    anim.draw(2)
    assert np.array_equal(anim.data(anim.axes_lines["top.x"]), np.vstack([c[2], tr["top.x"][2]]))
    assert Image.open(res.animate(tmp_path / "top.gif", frames=6)).n_frames == 6


@pytest.fixture(scope="module")
def cartesian_double_pendulum():
    """Two bobs in Cartesian coordinates held by two rods written as constraints: the
    unconstrained model's geometry has no rods, the runs keep both."""
    m = lcg.Model("cartesian_double_pendulum")
    x1, y1, x2, y2 = m.coordinates("x1 y1 x2 y2")
    m.particle("bob1", 1.0, (x1, y1))
    m.particle("bob2", 1.0, (x2, y2))
    m.gravity(9.81)
    system = lcg.ConstrainedSystem(m, holonomic=[x1**2 + y1**2 - 1, (x2 - x1)**2 + (y2 - y1)**2 - 0.25])
    a, b = 0.3, -0.2  # small swings: minimal coordinates stay on one branch (no square root at 0)
    q0 = [np.sin(a), -np.cos(a), np.sin(a) + 0.5 * np.sin(b), -np.cos(a) - 0.5 * np.cos(b)]
    return system, q0


@pytest.mark.parametrize("formulation", ["index1", "ggl", "minimal"])
def test_constrained_runs_draw_the_rods_their_constraints_keep(cartesian_double_pendulum, formulation, tmp_path):
    system, q0 = cartesian_double_pendulum
    res = lcg.compile_constrained(system, formulation).simulate(T, q0=q0, v0=[0.0] * 4, rtol=1e-10, atol=1e-12)
    d = res.drawn()
    assert sorted(d.links) == [("bob1", "bob2"), ("origin", "bob1")]  # bob2 swings: no rod to the origin
    assert d.pivots == {"origin": (0.0, 0.0)}
    tracks = res.tracks()
    assert np.allclose(np.hypot(*tracks["bob1"].T), 1.0, atol=1e-6)  # the rod lengths of the constraints
    assert np.allclose(np.hypot(*(tracks["bob2"] - tracks["bob1"]).T), 0.5, atol=1e-6)
    assert np.allclose(tracks["bob2"][:, 0], res["x2"]) and np.allclose(tracks["bob2"][:, 1], res["y2"])
    assert res.model_name == "cartesian_double_pendulum"
    gif = res.animate(tmp_path / f"{formulation}.gif", frames=5)
    assert Image.open(gif).n_frames == 5
    assert sorted(pickle.loads(pickle.dumps(res)).drawn().links) == sorted(d.links)


def test_rigid_body_trees_draw_joints_centres_of_mass_and_frame_axes(tmp_path):
    """The two-link arm of examples/two_link_arm.urdf (rods hanging along -z, joints about y):
    joints and centres of mass where the forward kinematics put them, lines along the tree."""
    from pathlib import Path
    arm = lcg.urdf.load(Path(__file__).resolve().parents[1] / "examples" / "two_link_arm.urdf")
    res = lcg.compile_model(arm).simulate(T, q0=[0.7, -0.4], rtol=1e-10, atol=1e-12)
    d = res.drawn()
    assert sorted(d.links) == [("forearm", "forearm.com"), ("upper_arm", "forearm"), ("upper_arm", "upper_arm.com")]
    tr = res.tracks()
    q1, q2 = res[arm.coords[0].name], res[arm.coords[1].name]
    zero = np.zeros_like(q1)
    assert np.allclose(tr["upper_arm"], 0.0, atol=1e-14) and "upper_arm" in d.fixed  # the shoulder
    assert np.allclose(tr["upper_arm.com"], np.column_stack([-0.5 * np.sin(q1), zero, -0.5 * np.cos(q1)]))
    assert np.allclose(tr["forearm"], np.column_stack([-np.sin(q1), zero, -np.cos(q1)]))  # the elbow
    assert np.allclose(tr["forearm.com"], np.column_stack([-np.sin(q1) - 0.4 * np.sin(q1 + q2), zero,
                                                           -np.cos(q1) - 0.4 * np.cos(q1 + q2)]))
    # frame axes on the bodies: the forearm's z axis points from its elbow to its centre of mass' opposite
    tip = tr["forearm.z"] - tr["forearm.com"]
    along = (tr["forearm"] - tr["forearm.com"]) / 0.4
    assert np.allclose(tip / np.linalg.norm(tip, axis=1)[:, None], along)
    assert Image.open(res.animate(tmp_path / "arm.gif", frames=4)).n_frames == 4


def test_a_top_on_a_ball_joint_is_drawn_from_its_link(tmp_path):
    m = lcg.Model("top")
    m.link("top", joint=lcg.Joint.spherical("pivot", rotation="ZYX"), mass=1.0, com=(0, 0, 0.3), inertia=(0.02, 0.02, 0.04))
    m.gravity(9.81)
    res = lcg.compile_model(m).simulate(T, q0=[0.0, 0.2, 0.0], v0=[0.0, 0.0, 30.0], rtol=1e-10, atol=1e-12)
    d = res.drawn()
    assert d.links == [("top", "top.com")] and d.fixed == ("top",) and d.dim == 3
    tr = res.tracks()
    assert np.allclose(np.linalg.norm(tr["top.com"], axis=1), 0.3)  # the centre of mass stays 0.3 from the pivot
    tip = tr["top.z"] - tr["top.com"]  # the symmetry axis runs through the pivot
    assert np.allclose(np.cross(tip, tr["top.com"]), 0.0, atol=1e-12)
    assert Image.open(res.animate(tmp_path / "top.gif", frames=4)).n_frames == 4


def test_springs_are_drawn_between_their_ends(tmp_path):
    """A bob hanging from a fixed anchor by a spring (no rod: its length changes), and a second
    spring to a wall given as a bare position."""
    m = lcg.Model("spring_pendulum")
    x, y = m.coordinates("x y")
    m.point("anchor", (0, 0))
    m.particle("bob", 1.0, (x, y))
    m.spring("anchor", "bob", 40.0, rest_length=1.0)
    m.spring("bob", (2, -1), 5.0)
    m.gravity(9.81)
    res = lcg.compile_model(m).simulate(T, q0=[0.3, -1.2], rtol=1e-10, atol=1e-12)
    d = res.drawn()
    assert d.springs == [("anchor", "bob"), ("bob", "spring1.b")]
    assert d.links == [] and set(d.fixed) == {"anchor", "spring1.b"}  # the spring's length varies: no rod
    tracks = res.tracks()
    assert np.allclose(tracks["spring1.b"], [2.0, -1.0])
    anim = Animator(d, res.t, tracks, res.t[[0, 20]])
    anim.draw(1)
    line = anim.data(anim.springs[("anchor", "bob")])
    assert np.allclose(line[0], [0.0, 0.0]) and np.allclose(line[-1], tracks["bob"][20])  # from the anchor to the bob
    length = np.linalg.norm(tracks["bob"][20])
    axis = tracks["bob"][20] / length
    along = line @ axis
    assert np.all(np.diff(along) > 0) and along[-1] == pytest.approx(length)  # a zigzag along the spring
    across = line - np.outer(along, axis)
    assert np.max(np.linalg.norm(across, axis=1)) > 0.02 * length  # ... of some width
    assert Image.open(res.animate(tmp_path / "spring.gif", frames=4)).n_frames == 4
