"""How objects show in a notebook (lagcodegen.notebook) and the result's pictures and tables:
reprs of bounded size that say what they leave out, plots titled by the model with a panel per
kind of output, x-y paths, to_pandas."""

import sys
import types

import numpy as np
import pytest
import sympy as sp

import lagcodegen as lcg
from lagcodegen.errors import LagcodegenError
from lagcodegen.notebook import MAX_EQUATIONS
from lagcodegen.result import Result


@pytest.fixture(scope="module")
def dp():
    model = lcg.systems.double_pendulum()
    sim = lcg.compile_model(model, outputs=["energy", "jacobi_h"])
    res = sim.simulate(np.linspace(0, 2, 201), q0=[1.0, 0.5])
    return model, sim, res


def test_model_reprs_name_what_it_holds():
    m = lcg.systems.double_pendulum()
    html = m._repr_html_()
    for word in ("double_pendulum", "theta1", "theta2", "l1 = 1", "g = 9.81", "bob1", "bob2", "Particle"):
        assert word in html
    latex = m._repr_latex_()
    assert latex.startswith("$") and latex.endswith("$") and r"\theta_{1}" in latex
    big = lcg.systems.n_link_pendulum(20)
    assert "... (8 more)" in big._repr_html_() and len(big._repr_html_()) < 3000


def test_equations_show_dotted_and_simplified():
    eom = lcg.derive(lcg.systems.double_pendulum())
    tex = eom._repr_latex_()
    # Lagrange's equations of the double pendulum, in their textbook form
    assert r"\ddot{\theta_{1}}" in tex and r"\ddot{\theta_{2}}" in tex and r"\dot{\theta_{2}}^{2}" in tex
    assert r"\cos{\left(\theta_{1} - \theta_{2} \right)}" in tex
    assert "theta1_dot" not in tex and tex.count(r"\\") == 1  # two rows
    assert "Lagrange's equations of double_pendulum" in eom._repr_html_()


def test_a_20_link_chain_repr_stays_small():
    eom = lcg.derive(lcg.systems.n_link_pendulum(20))
    tex, html = eom._repr_latex_(), eom._repr_html_()
    assert len(tex) < 10_000 and len(html) < 10_000
    assert f"... ({20 - MAX_EQUATIONS} more)" in tex
    assert "more terms" in tex  # each row's 20 terms cut too


def test_compiled_model_repr(dp):
    _, sim, _ = dp
    html = sim._repr_html_()
    for word in ("double_pendulum", "n = 2 coordinates, 4 states", "theta1_dot", "energy", "jacobi_h", "rhs",
                 "jac", "outputs", "analytic", str(sim.path)):
        assert word in html, word
    assert "kkt" not in html


def test_result_repr_and_to_pandas(dp, monkeypatch):
    _, _, res = dp
    html = res._repr_html_()
    assert "Result of double_pendulum" in html and "201 rows x 7 columns" in html
    assert f"{res['theta1'][-1]:.6g}" in html and "steps" in html and html.count("<tr>") <= 30
    assert f"{res['theta1'][100]:.6g}" not in html and len(html) < 5000  # the head and the last row only
    monkeypatch.setitem(sys.modules, "pandas", None)  # pandas missing
    with pytest.raises(LagcodegenError, match="needs pandas"):
        res.to_pandas()
    made = {}
    fake = types.ModuleType("pandas")
    fake.DataFrame = lambda data: made.setdefault("frame", data)
    monkeypatch.setitem(sys.modules, "pandas", fake)
    frame = res.to_pandas()
    assert list(frame) == ["t", "theta1", "theta2", "theta1_dot", "theta2_dot", "energy", "jacobi_h"]
    assert np.array_equal(frame["theta2_dot"], res["theta2_dot"])


def test_plot_without_path_returns_the_figure_titled_and_paneled(dp):
    _, _, res = dp
    fig = res.plot()
    assert fig._suptitle.get_text() == "double_pendulum"
    axes = fig.axes
    # theta1, theta2, then energy and h each in their own panel
    assert [ax.get_ylabel() for ax in axes] == ["theta1", "theta2", "energy", "jacobi_h"]
    assert np.array_equal(axes[2].lines[0].get_ydata(), res["energy"])
    custom = res.plot(what=["theta1", ["theta1_dot", "theta2_dot"]], title="mine")
    assert custom._suptitle.get_text() == "mine" and len(custom.axes[1].lines) == 2


def test_plot_panels_for_multipliers_and_residuals(tmp_path):
    t = np.linspace(0, 1, 11)
    res = Result(t=t, y=np.column_stack([t, t, t, t]), state_names=["x", "y", "x_dot", "y_dot"], n_coordinates=2,
                 outputs={"energy": t, "lambda_0": t, "g_0": t, "gdot_0": t})
    assert res.panels() == [["x"], ["y"], ["energy"], ["lambda_0"], ["g_0", "gdot_0"]]
    path = res.plot(tmp_path / "c.png")
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_xy_path_of_a_planar_particle_is_the_orbit():
    sim = lcg.compile_model(lcg.systems.central_potential())
    res = sim.simulate(np.linspace(0, 10, 301), q0=[1.0, 0.0], v0=[0.0, 1.2])
    fig = res.plot(xy=True)
    (line,) = fig.axes[0].lines
    x, y = line.get_data()
    assert np.allclose(x, res["r"] * np.cos(res["phi"]), atol=1e-12)
    assert np.allclose(y, res["r"] * np.sin(res["phi"]), atol=1e-12)
    assert fig._suptitle.get_text() == "central"
    with pytest.raises(LagcodegenError, match="not a point"):
        res.plot(xy="moon")
    phase = res.plot(phase=True)
    assert np.array_equal(phase.axes[0].lines[0].get_xdata(), res["r"])
    assert np.array_equal(phase.axes[0].lines[0].get_ydata(), res["r_dot"])
    sph = lcg.compile_model(lcg.systems.spherical_pendulum()).simulate([0, 1], q0=[0.5, 0.0])
    with pytest.raises(LagcodegenError, match="no planar"):
        sph.plot(xy=True)


def test_model_latex_escapes_names_and_bounds_terms():
    m = lcg.Model("my_model")
    x, = m.coordinates("x")
    m.kinetic_energy(m.dot(x) ** 2 / 2, label="T_1")
    for k in range(10):
        m.potential_energy(sp.Integer(k + 1) * x ** 2, label=f"V_{k}")
    tex = m._repr_latex_()
    assert r"my\_model" in tex and r"\dot{x}^{2}" in tex and "more" in tex


def test_a_plot_made_without_pyplot_draws_itself_in_a_notebook(dp):
    """A fresh notebook (no pyplot, so no inline formatter for matplotlib figures) showed
    `<Figure size 800x640 with 3 Axes>`: the figures res.plot() returns carry a _repr_png_ that
    IPython's PNG formatter calls."""
    _, _, res = dp
    for fig in (res.plot(), res.plot(phase=True), res.plot(xy=True)):
        png = fig._repr_png_()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
        assert (width, height) == (round(fig.get_figwidth() * fig.dpi), round(fig.get_figheight() * fig.dpi))
    import pickle
    assert pickle.loads(pickle.dumps(res.plot()))._repr_png_()[:4] == b"\x89PNG"


def test_ipythons_png_formatter_draws_a_plot(dp):
    """What a notebook asks of the figure: IPython's PNG formatter (no pyplot imported) gives the PNG."""
    formatters = pytest.importorskip("IPython.core.formatters")
    _, _, res = dp
    assert formatters.PNGFormatter()(res.plot())[:4] == b"\x89PNG"
