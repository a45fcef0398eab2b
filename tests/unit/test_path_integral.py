"""The path integral of p dV (dE along the path): exact on cubic paths, whatever the steps."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.fe.continuation import PathPoint
from snapjump_cli.fe.axisym.metrics import path_p_dV


def _points(s: np.ndarray, sV: float, sp: float) -> list[PathPoint]:
    V = lambda x: 2.0 + 3.0 * x - 1.5 * x**2 + 0.4 * x**3  # noqa: E731 - cubic in the arc length
    dV = lambda x: 3.0 - 3.0 * x + 1.2 * x**2  # noqa: E731
    p = lambda x: 0.1 + 0.5 * x + 0.2 * x**2 - 0.3 * x**3  # noqa: E731
    dp = lambda x: 0.5 + 0.4 * x - 0.9 * x**2  # noqa: E731
    return [PathPoint(np.zeros(2), p(x), np.array([V(x) / sV, p(x) / sp, 0.0]),
                      np.array([dV(x) / sV, dp(x) / sp, 0.0]), np.zeros(2), dp(x), float(x)) for x in s]


def test_path_integral_is_exact_for_cubic_paths_on_uneven_steps():
    sV, sp = 2.0, 0.5
    s = np.array([0.0, 0.05, 0.3, 0.31, 1.0, 1.7, 2.0])
    x = np.linspace(0.0, 2.0, 200001)  # reference: p dV/ds on a fine grid (trapezoid, error ~1e-10)
    V = 2.0 + 3.0 * x - 1.5 * x**2 + 0.4 * x**3
    p = 0.1 + 0.5 * x + 0.2 * x**2 - 0.3 * x**3
    exact = np.trapezoid(p * np.gradient(V, x), x)
    pts = _points(s, sV, sp)
    assert path_p_dV(pts, sV, sp) == pytest.approx(exact, rel=1e-8)
    per_segment = sum(path_p_dV([a, b], sV, sp) for a, b in zip(pts[:-1], pts[1:]))
    assert per_segment == pytest.approx(exact, rel=1e-8)
