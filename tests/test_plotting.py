"""Figures come back as matplotlib Figures with labelled axes."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from preisach import PreisachModel
from preisach.plotting import boundary_polyline, plot_boundary, plot_major_loop


@pytest.fixture(scope="module")
def model():
    return PreisachModel.builtin("ss15-1hz", levels=41)


def test_major_loop_figure(model):
    fig = plot_major_loop(model, n_fod=5)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "input u (V)" and ax.get_ylabel() == "output y (V)"
    assert len(ax.lines) == 6


@pytest.mark.parametrize("coords", ["alpha-beta", "r-s"])
def test_boundary_figure(model, coords):
    for st in (model.neutral_state(30.0), model.state_from_extrema([60, -40, 20]),
               model.negative_saturation()):
        fig = plot_boundary(st, coords=coords)
        assert isinstance(fig, Figure)
    with pytest.raises(ValueError, match="coords"):
        plot_boundary(model.anhysteretic_state(), coords="xy")


def test_boundary_polyline_follows_the_state(model):
    s = model.state_from_extrema([60.0, -40.0, 20.0])
    p = boundary_polyline(s)
    # Staircase corners of the reduced memory sequence, ending on the diagonal at u.
    assert (60.0, -100.0) in map(tuple, p) and (60.0, -40.0) in map(tuple, p)
    assert tuple(p[-1]) == (20.0, 20.0)
    n = boundary_polyline(model.neutral_state(30.0), points_per_piece=11)
    slope = n[-12:-1]
    np.testing.assert_allclose(slope[:, 0] + slope[:, 1], 60.0)  # alpha + beta = 2 l
