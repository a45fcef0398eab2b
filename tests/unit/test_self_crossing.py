"""The self-crossing test of a traced path: polyline and cubic Hermite forms."""
from __future__ import annotations

import numpy as np

from snapjump_cli.fe.axisym.metrics import path_self_crosses


def _hermite_data(x, y, dx, dy):
    """Points and per-segment end derivatives of the curve sampled at parameter steps of 1."""
    seg = lambda d: np.stack([d[:-1], d[1:]], axis=1)  # noqa: E731
    return np.asarray(x), np.asarray(y), seg(np.asarray(dx)), seg(np.asarray(dy))


def test_a_figure_eight_crosses_itself_in_both_forms():
    t = np.linspace(2.5, 2 * np.pi + 0.7, 13)  # (0, 0) at t = pi and 2 pi, both between samples
    h = t[1] - t[0]
    x, y = np.sin(t), np.sin(2 * t)
    dx, dy = np.cos(t) * h, 2 * np.cos(2 * t) * h
    assert path_self_crosses(x, y)
    assert path_self_crosses(*_hermite_data(x, y, dx, dy))


def test_an_arc_and_a_short_stroke_inside_its_bulge_do_not_cross_though_the_chord_does():
    # one long step from (0, 0) to (1, 0) that bulges up to y = 0.375 (Hermite ends (1, 1.5) and
    # (1, -1.5)), then the path runs on to (0.5, 0.3) and down to (0.5, -0.1): the chord y = 0 of the
    # first step crosses the stroke, the curve passes above it
    x = [0.0, 1.0, 0.5, 0.5]
    y = [0.0, 0.0, 0.3, -0.1]
    dx = [1.0, 1.0, -0.5, 0.0, 0.0]
    dy = [1.5, -1.5, 0.3, -0.4, -0.4]
    assert path_self_crosses(np.array(x), np.array(y))  # the polyline's artefact
    dV = np.array([[dx[0], dx[1]], [-0.5, -0.5], [0.0, 0.0]])
    dp = np.array([[dy[0], dy[1]], [0.3, 0.3], [-0.4, -0.4]])
    assert not path_self_crosses(np.array(x), np.array(y), dV, dp)


def test_a_stroke_through_the_bulge_of_a_long_step_crosses_though_the_chord_does_not():
    # a stroke from (0.55, 0.45) down to (0.55, 0.3), straight on to (0, 0), then the long step to
    # (1, 0) that bulges up to y = 0.375 at x = 0.5: the curve crosses the stroke, the chord does not
    x = np.array([0.55, 0.55, 0.0, 1.0])
    y = np.array([0.45, 0.3, 0.0, 0.0])
    dV = np.array([[0.0, 0.0], [-0.55, -0.55], [1.0, 1.0]])
    dp = np.array([[-0.15, -0.15], [-0.3, -0.3], [1.5, -1.5]])
    assert not path_self_crosses(x, y)
    assert path_self_crosses(x, y, dV, dp)


def test_a_smooth_spiral_without_crossings_is_clean_at_any_sampling():
    for m in (6, 12, 40):
        t = np.linspace(0.0, 3 * np.pi, m)
        h = t[1] - t[0]
        r = 1.0 + 0.3 * t
        x, y = r * np.cos(t), r * np.sin(t)
        dx = (0.3 * np.cos(t) - r * np.sin(t)) * h
        dy = (0.3 * np.sin(t) + r * np.cos(t)) * h
        assert not path_self_crosses(*_hermite_data(x, y, dx, dy))
