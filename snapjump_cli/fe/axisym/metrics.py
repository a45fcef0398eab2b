"""The reported snap metrics (docs/physics.md section 5) of a traced and characterised path.

Pure computation, no solving: from the model, the traced path and its snap states (the upper
state at ``V*`` and the lower state, :mod:`snapjump_cli.fe.axisym.snap`, :mod:`snapjump_cli.fe.axisym.lower_state`)
to the metrics dict (SI units; the stable keys are :data:`snapjump_cli.sweep.rows.RESULT_KEYS`) and the
curve arrays.

``dE`` is computed both as the strain-energy difference of the two states and as
``-integral p dV`` along the path between them (cubic Hermite interpolation of ``V(s)`` and
``p(s)`` from the tangents, so the quadrature is fourth-order accurate in the step); the second
only where the lower state lies on the path.
"""
from __future__ import annotations

import math

import numpy as np

from snapjump_cli.fe.continuation import hermite
from snapjump_cli.fe.continuation import Path, PathPoint
from snapjump_cli.mesh.data import solid_volumes
from snapjump_cli.schema import SNAP_VALUE_KEYS
from snapjump_cli.fe.axisym.model import Model
from snapjump_cli.fe.axisym.snap import SnapStates

__all__ = ["snap_metrics", "scene_curve", "snap_sequence", "path_p_dV", "path_self_crosses", "loading_peak",
           "path_derivatives"]

_G3 = np.polynomial.legendre.leggauss(4)


def path_p_dV(points: list[PathPoint], sV: float, sp: float) -> float:
    """``integral p dV`` along the path through ``points`` (scaled units): on each segment the cubic
    Hermite interpolation of ``V`` and ``p`` in the arc length (the points' ``s``) from the end
    values and tangents, 4-point Gauss quadrature; all segments at once."""
    V = np.array([pt.zeta[0] for pt in points]) * sV
    p = np.array([pt.p for pt in points])
    h = np.diff([pt.s for pt in points])
    tV = np.array([pt.tangent[0] for pt in points]) * sV
    tp = np.array([pt.tangent[1] for pt in points]) * sp
    x, w = _G3
    t = (0.5 * (x + 1.0))[:, None]  # (4, 1): the Gauss points of every segment
    h00, h10, h01, h11 = hermite.basis(t)
    d00 = 6 * t**2 - 6 * t
    d10 = 3 * t**2 - 4 * t + 1
    d01 = -6 * t**2 + 6 * t
    d11 = 3 * t**2 - 2 * t
    pq = h00 * p[:-1] + h10 * (tp[:-1] * h) + h01 * p[1:] + h11 * (tp[1:] * h)  # (4, segments)
    Vt = d00 * V[:-1] + d10 * (tV[:-1] * h) + d01 * V[1:] + d11 * (tV[1:] * h)  # dV/dt, t in [0, 1]
    return float(np.sum(0.5 * (w[:, None] * pq * Vt).sum(axis=0)))


def _orient(a, b, c):
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _segments_cross(a1, b1, a2, b2) -> np.ndarray:
    """Whether segments ``a1 b1`` and ``a2 b2`` cross (proper intersection), elementwise."""
    return (_orient(a1, b1, a2) * _orient(a1, b1, b2) < 0) & (_orient(a2, b2, a1) * _orient(a2, b2, b1) < 0)


def path_self_crosses(V: np.ndarray, p: np.ndarray, dV: np.ndarray | None = None, dp: np.ndarray | None = None,
                      sub: int = 8) -> bool:
    """Whether the path ``(V, p)`` crosses itself.

    Without derivatives: the polyline through the points (non-adjacent segments intersect). With
    ``dV``, ``dp`` (shape ``(n - 1, 2)``: for each segment, the derivatives at its start and its end
    with respect to a parameter running from 0 to 1 along it, i.e. the arc-length derivatives times
    the segment's arc length; :func:`path_derivatives`): the cubic Hermite curve through the points,
    each segment drawn as ``sub`` chords. The Hermite curve is what the energy integral
    ``-integral p dV`` uses too; unlike the polyline it does not depend on where the steps fell (the
    chord of a long step over a bend can cut a branch that the path itself passes by).
    """
    P = np.stack([np.asarray(V, float), np.asarray(p, float)], axis=1)
    n = len(P) - 1
    if n < 2 or (dV is None and n < 3):
        return False
    scale = np.ptp(P, axis=0)
    scale[scale == 0] = 1.0
    P = P / scale
    if dV is None:
        A, B = P[:-1], P[1:]
        i, j = np.triu_indices(n, k=2)
        return bool(np.any(_segments_cross(A[i], B[i], A[j], B[j])))
    D = np.stack([np.asarray(dV, float), np.asarray(dp, float)], axis=-1) / scale  # (n, 2 ends, 2)
    # Bezier control points of each segment: the curve lies in their convex hull (a bounding box)
    C = np.stack([P[:-1], P[:-1] + D[:, 0] / 3.0, P[1:] - D[:, 1] / 3.0, P[1:]], axis=1)  # (n, 4, 2)
    lo, hi = C.min(axis=1), C.max(axis=1)
    i, j = np.triu_indices(n, k=1)
    near = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    i, j = i[near], j[near]
    if len(i) == 0:
        return False
    t = np.linspace(0.0, 1.0, sub + 1)[:, None]
    h00, h10, h01, h11 = hermite.basis(t)

    def curve(k):  # (len(k), sub + 1, 2)
        return (h00 * P[k][:, None] + h10 * D[k][:, None, 0] + h01 * P[k + 1][:, None] + h11 * D[k][:, None, 1])

    Qi, Qj = curve(i), curve(j)
    a1, b1 = Qi[:, :-1, None], Qi[:, 1:, None]  # (m, sub, 1, 2)
    a2, b2 = Qj[:, None, :-1], Qj[:, None, 1:]  # (m, 1, sub, 2)
    hit = _segments_cross(a1, b1, a2, b2)  # (m, sub, sub)
    adjacent = j == i + 1
    hit[adjacent, -1, 0] = False  # the two chords that meet at the shared point
    return bool(hit.any())


def path_derivatives(points: list[PathPoint], sV: float, sp: float) -> tuple[np.ndarray, np.ndarray]:
    """End derivatives of each segment of the path in ``(V, p)`` (scaled units) for
    :func:`path_self_crosses`: ``d/dt`` with ``t`` in [0, 1] along the segment."""
    s = np.array([pt.s for pt in points])
    h = np.diff(s)[:, None]
    tV = np.array([pt.tangent[0] * sV for pt in points])
    tp = np.array([pt.tangent[1] * sp for pt in points])
    dV = np.stack([tV[:-1], tV[1:]], axis=1) * h
    dp = np.stack([tp[:-1], tp[1:]], axis=1) * h
    return dV, dp


def loading_peak(points: list[PathPoint], states: SnapStates, sV: float, sp: float) -> float:
    """The largest pressure (scaled) on the loading path: from the start up to the upper state,
    or along the whole traced path when there is no volume limit.

    Taken on the path's cubic Hermite curve (:func:`snapjump_cli.fe.continuation.hermite.segment_maxima`): the
    points alone miss a smooth maximum by the curvature times the square of the step. The path
    beyond the upper state is left out: where it rises again, how far it was traced (the trace
    stops once the snap is characterised) would set the value.
    """
    pts = list(points)
    up = states.upper
    top = -math.inf
    if up is not None and states.k_before is not None:
        pts = pts[: states.k_before + 1]
        if up.s > pts[-1].s:
            pts.append(up)
        else:  # (an upper state without an arc length beyond its step's start: its value only)
            top = float(up.p)
    p = np.array([pt.p for pt in pts])
    top = max(top, float(p.max()))
    if len(pts) < 2:
        return top
    _, dp = path_derivatives(pts, sV, sp)
    return max(top, float(np.max(hermite.segment_maxima(p[:-1], dp[:, 0], p[1:], dp[:, 1]))))


def snap_sequence(path: Path, states: SnapStates) -> list[PathPoint]:
    """The states of the snap: the upper state, the path points after it and the lower state when
    the lower state lies on the path, else just the two states."""
    up, lo = states.upper, states.lower
    if states.lower_method == "path":
        return [up] + path.points[states.k_before + 1 : states.k_return] + [lo]
    return [up, lo]


def _y(model: Model, u: np.ndarray, node: int) -> float:
    """Height of ``node`` in the configuration ``u`` [m]."""
    return model.positions(u)[node, 1] * model.L


def snap_metrics(
    model: Model,
    path: Path,
    states: SnapStates,
    scales: tuple[float, float, float],
    *,
    lower_solver: str | None = None,
    lower_note: str = "",
    outer_alone: bool = False,
    outer_u: np.ndarray | None = None,
) -> dict:
    """The snap metrics of a traced path (SI units).

    Parameters
    ----------
    model : the FE model the path was traced with (its mesh gives the poles and solid volumes)
    path : the traced path
    states : the upper and lower states (``states.lower`` set whenever ``states.upper`` is)
    scales : the path-measure scales ``(s_V, s_p, s_w)`` of the trace
    lower_solver : how a lower state off the path was found (``lower_state_solver``), else ``None``
    lower_note : why the path's own lower state was rejected (``lower_state_note``)
    outer_alone : an outer cap alone: report ``E_o_J``, its stored energy at ``outer_u`` (the
        state at ``p / mu_o = 0.5``; ``None`` if it was not found)

    Returns
    -------
    dict
        The metrics, the path's counts and diagnostics (not the timings).
    """
    pts = path.points
    st = states
    sV, sp = scales[0], scales[1]
    mesh = model.mesh
    L, S = model.L, model.S
    pole1 = int(mesh.node_sets["pole_lower"][0])
    pole2 = int(mesh.node_sets["pole_upper"][0])
    E_unit = S * L**3
    metrics: dict = {k: None for k in SNAP_VALUE_KEYS}
    V_curve = np.array([pt.zeta[0] * sV for pt in pts])
    p_curve = np.array([pt.p for pt in pts])
    dV_seg, dp_seg = path_derivatives(pts, sV, sp)
    metrics["p_max_Pa"] = loading_peak(pts, st, sV, sp) * S
    metrics["self_crossing"] = path_self_crosses(V_curve, p_curve, dV_seg, dp_seg)
    metrics["snaps"] = st.upper is not None
    if lower_solver is not None:
        metrics["lower_state_solver"] = lower_solver
    metrics["lower_state_method"] = st.lower_method or None
    if outer_alone:
        metrics["E_o_J"] = model.energy(outer_u) * E_unit if outer_u is not None else None
    if st.upper is not None:
        up, lo = st.upper, st.lower
        W_up, W_lo = model.energy(up.u), model.energy(lo.u)
        dE_energy = W_up - W_lo
        if st.lower_method == "path":  # path integral: upper -> points after it -> lower
            dE_path = -path_p_dV(snap_sequence(path, st), sV, sp)
        else:  # the descent state is not on the traced path: no path integral
            dE_path = float("nan")
        metrics.update(
            dE_J=dE_energy * E_unit, dE_energy_J=dE_energy * E_unit,
            dE_path_J=dE_path * E_unit if math.isfinite(dE_path) else None,
            dE_rel_diff=abs(dE_energy - dE_path) / max(abs(dE_energy), 1e-300) if math.isfinite(dE_path) else None,
            dE_norm=dE_energy * E_unit / (S * L**3),
            p_star_Pa=up.p * S, V_star_m3=up.zeta[0] * sV * L**3,
            dy_pole_m=_y(model, up.u, pole1) - _y(model, lo.u, pole1),
            dy_pole_upper_m=_y(model, up.u, pole2) - _y(model, lo.u, pole2),
        )
        metrics["dy_pole_norm"] = metrics["dy_pole_m"] / L
        metrics["p_lower_Pa"] = lo.p * S
        if "ground" in mesh.node_sets and len(mesh.node_sets["ground"]):
            xg = model.positions(up.u)[mesh.node_sets["ground"], 1] * L
            metrics["h_imp_m"] = _y(model, up.u, pole1) - float(xg.min())
        if "outer_pole_lower" in mesh.node_sets:
            xs = model.positions(up.u)[:, 1] * L
            n = mesh.node_sets
            mid_o = 0.5 * (xs[n["outer_pole_lower"][0]] + xs[n["outer_pole_upper"][0]])
            mid_i = 0.5 * (xs[pole1] + xs[pole2])
            metrics["L0_m"] = float(mid_o - mid_i)
    else:
        metrics.update(dE_J=0.0, dE_norm=0.0)
    vols = solid_volumes(mesh)
    metrics.update(
        n_steps=len(pts) - 1, n_newton=path.n_newton, n_rejected=path.n_rejected, n_bifurcations=path.n_bifurcations,
        n_nodes=mesh.n_nodes, n_elements=mesh.n_elements, n_dofs=model.n,
        V_inner_solid_m3=vols.get("inner_solid"), V_outer_solid_m3=vols.get("outer_solid"),
        max_dilatation=float(max(model.max_dilatation(pt.u) for pt in ([st.upper, st.lower] if st.lower else pts[-1:]))),
        stop_reason=path.stop_reason, lower_state_note=lower_note, fold_note=st.fold_note,
    )
    return metrics


def scene_curve(model: Model, path: Path, states: SnapStates, scales: tuple[float, float, float], V0: float) -> dict:
    """The traced path in SI units: ``p_Pa``, ``V_m3``, ``y_pole_m``, ``energy_J``, ``s`` per point,
    the reference ``V0_m3`` (``V0``: the scaled cavity volume at ``u = 0``), the units and, for a
    snap, ``snap_V_m3`` / ``snap_p_Pa`` (the states of :func:`snap_sequence`)."""
    pts = path.points
    sV = scales[0]
    L, S = model.L, model.S
    pole1 = int(model.mesh.node_sets["pole_lower"][0])
    E_unit = S * L**3
    curve = {
        "p0_Pa": 0.0,
        "V0_m3": V0 * L**3,
        "L_m": L,
        "mu_Pa": S,
        "p_Pa": np.array([pt.p for pt in pts]) * S,
        "V_m3": np.array([pt.zeta[0] * sV for pt in pts]) * L**3,
        "y_pole_m": np.array([_y(model, pt.u, pole1) for pt in pts]),
        "energy_J": np.array([model.energy(pt.u) for pt in pts]) * E_unit,
        "s": np.array([pt.s for pt in pts]),
    }
    if states.upper is not None:
        seq = snap_sequence(path, states)
        curve["snap_V_m3"] = np.array([pt.zeta[0] * sV for pt in seq]) * L**3
        curve["snap_p_Pa"] = np.array([pt.p for pt in seq]) * S
    return curve
