"""Sensitivity directions as values (lagcodegen.solvers.direction): every spelling read in one
place, with the errors the sensitivity runs, fits and the command line report."""

import pytest

from lagcodegen import LagcodegenError
from lagcodegen.solvers.direction import Direction, parse_all

PARAMS, COORDS, STATES = ["g", "k_dot(0)x"], ["x", "theta", "x_dot"], ["x", "theta", "x_dot", "x_dot_dot",
                                                                     "theta_dot", "x_dot_dot_dot", "z"]


@pytest.mark.parametrize("name, kind, target, index", [
    ("g", "parameter", "g", None),
    ("x(0)", "position", "x", 0),
    ("theta_dot(0)", "velocity", "theta", 4),
    ("x_dot(0)", "velocity", "x", 3),        # the velocity of x, although a coordinate x_dot exists
    ("x_dot_dot(0)", "velocity", "x_dot", 5),
    ("z(0)", "state", "z", 6),
])
def test_every_spelling(name, kind, target, index):
    d = Direction.parse(name, params=PARAMS, coords=COORDS, states=STATES)
    assert (d.name, d.kind, d.target) == (name, kind, target)
    if index is None:
        with pytest.raises(ValueError):
            d.state_index(COORDS, STATES)
    else:
        assert d.state_index(COORDS, STATES) == index


def test_refusals_name_the_direction():
    with pytest.raises(LagcodegenError, match=r"'y\(0\)' names no initial value \(coordinates: x, theta, x_dot"):
        Direction.parse("y(0)", params=PARAMS, coords=COORDS)
    with pytest.raises(LagcodegenError, match="'h' is neither a run-time parameter"):
        Direction.parse("h", params=PARAMS, coords=COORDS)
    with pytest.raises(LagcodegenError, match="fit: 3 is not a name"):
        Direction.parse(3, params=PARAMS, coords=COORDS, what="fit")
    with pytest.raises(LagcodegenError, match="given twice"):
        parse_all(["g", "x(0)", "g"], params=PARAMS, coords=COORDS)
    with pytest.raises(LagcodegenError, match="at least one"):
        parse_all([], params=PARAMS, coords=COORDS)
    with pytest.raises(LagcodegenError, match="folded into the code as a constant; list it in runtime_parameters"):
        parse_all(["m"], params=PARAMS, coords=COORDS, folded={"m": 1.0}, listed_in="runtime_parameters")
    long = "q" * 5000 + "(0)"
    with pytest.raises(LagcodegenError) as err:
        Direction.parse(long, params=PARAMS, coords=COORDS)
    assert len(str(err.value)) < 300
    assert [d.kind for d in parse_all("x(0)", params=PARAMS, coords=COORDS)] == ["position"]
