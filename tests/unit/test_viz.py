"""The states and fields that the pictures and the ParaView export show."""
from __future__ import annotations

import numpy as np
import pytest

from snapjump_cli.viz.fields import NODE_XI, nodal_stretch, principal_stretch


def _q9(r0: float, r1: float, y0: float, y1: float) -> tuple[np.ndarray, np.ndarray]:
    xi = NODE_XI[2]
    X = np.column_stack([r0 + (xi[:, 0] + 1) / 2 * (r1 - r0), y0 + (xi[:, 1] + 1) / 2 * (y1 - y0)])
    return X, np.arange(9)[None, :]


@pytest.mark.parametrize("r0", [0.0, 1.0])
def test_stretch_of_homogeneous_maps(r0):
    X, el = _q9(r0, r0 + 1.0, 0.0, 0.5)
    pts = np.array([[-0.7, 0.2], [0.0, 0.0], [1.0, 1.0], [-1.0, -1.0]])
    # r = a R, y = b Y: principal stretches a (radial), b (axial), a (hoop; on the axis its limit)
    for a, b in ((1.3, 0.9), (0.8, 1.25)):
        x = X * [a, b]
        assert np.allclose(principal_stretch(X, x, el, 2, pts), max(a, b), rtol=0, atol=1e-12)
        assert np.allclose(nodal_stretch(X, x, el, 2), max(a, b), rtol=0, atol=1e-12)
    # a rigid lift and the identity: 1
    assert np.allclose(principal_stretch(X, X + [0.0, 0.3], el, 2, pts), 1.0, atol=1e-12)
    # a shear y = Y + g R (no hoop change): the in-plane stretch sqrt(1 + g^2/2 + g sqrt(1 + g^2/4))
    g = 0.4
    x = X + np.column_stack([np.zeros(9), g * X[:, 0]])
    expect = np.sqrt(1 + g**2 / 2 + g * np.sqrt(1 + g**2 / 4))
    assert np.allclose(principal_stretch(X, x, el, 2, pts), expect, atol=1e-12)


def test_hoop_stretch_off_the_axis():
    X, el = _q9(1.0, 2.0, 0.0, 1.0)
    x = X + [0.5, 0.0]  # a uniform radial shift: in-plane rigid, hoop (R + 0.5) / R
    lam = principal_stretch(X, x, el, 2, NODE_XI[2])
    assert np.allclose(lam, (X[:, 0] + 0.5) / X[:, 0], atol=1e-12)


def test_shapes_draw_each_half_from_its_own_section():
    from snapjump_cli.geometry.caps import CapScene
    from snapjump_cli.mesh.build import mesh_scene
    from snapjump_cli.settings import MeshSettings
    from snapjump_cli.viz.shapes import SectionDrawing

    mesh = mesh_scene(CapScene(theta_deg=60, eta=8.5, bc="clamped"), MeshSettings(order=2, nt=1, aspect=4))
    d = SectionDrawing(mesh)
    X = mesh.nodes
    x = X + [0.0, 0.002]
    x_pi = X * [1.1, 1.0]
    polys, lam, lines = d.halves(x, x_pi)
    n = len(polys) // 2
    left, right = polys[:n], polys[n:]
    assert (left[..., 0] <= 1e-9).all() and (right[..., 0] >= -1e-9).all()
    # the right half is phi = 0 (a rigid lift: stretch 1), the left half phi = pi (hoop 1.1)
    assert np.allclose(lam[n:], 1.0, atol=1e-12) and np.allclose(lam[:n], 1.1, atol=1e-9)
    assert -left[..., 0].min() == pytest.approx(1.1 * right[..., 0].max(), rel=1e-9)
    # mirrored when there is no second section
    p2, l2, _ = d.halves(x)
    assert np.allclose(p2[:n, :, 0], -p2[n:, :, 0]) and np.allclose(l2, 1.0)


def test_steps_name_the_states_of_design_c():
    from snapjump_cli.geometry.designs import get_design
    from snapjump_cli.fe.solve import solve_checked
    from snapjump_cli.viz.states import path_steps

    res = solve_checked(get_design("C"))
    m, st = res.metrics, path_steps(res)
    names = [s for s in st.state if s]
    assert names == ["start", "p_max", "upper", "lower"]
    assert len(st) == len(res.path.points) + 3 and st.on_path.all()
    s = st.arc_length
    assert np.all(np.diff(s) >= 0)
    up, lo, pk = st.index("upper"), st.index("lower"), st.index("p_max")
    assert st.p_Pa[up] == m["p_star_Pa"] and st.V_m3[up] == m["V_star_m3"]
    assert st.V_m3[lo] == pytest.approx(m["V_star_m3"], rel=1e-9)
    assert st.y_pole_m[up] - st.y_pole_m[lo] == pytest.approx(m["dy_pole_m"], rel=1e-12)
    # the pressure maximum is a path state at least as high as every traced point before V*
    assert st.p_Pa[pk] >= st.p_Pa[: up + 1].max() - 1e-9 * st.p_Pa[pk]
    assert st.p_Pa[pk] == pytest.approx(m["p_max_Pa"], rel=1e-4)
    assert np.all(st.U[0] == 0.0)


def test_a_path_without_snap_gets_one_panel_for_its_last_state():
    from snapjump_cli.viz.shapes import key_shape_states
    from snapjump_cli.viz.states import Steps

    n, nn = 5, 3
    p = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    steps = Steps(U=np.zeros((n, nn, 2)), p_Pa=p, V_m3=p * 1e-6, y_pole_m=np.zeros(n), energy_J=np.zeros(n),
                  arc_length=np.arange(n, dtype=float), state=["start", "", "", "", "p_max"],
                  on_path=np.ones(n, bool))
    panels = key_shape_states(steps, np.zeros((nn, 2)))
    assert [s.label for s in panels] == ["undeformed", "pressure maximum"] and "no snap" in panels[1].note
    steps.state = ["start", "", "p_max", "", ""]
    panels = key_shape_states(steps, np.zeros((nn, 2)))
    assert [s.label for s in panels] == ["undeformed", "pressure maximum", "last traced state (no snap)"]
    assert panels[-1].p_Pa == 4.0
