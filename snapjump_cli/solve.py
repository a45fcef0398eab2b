"""One scene, end to end: mesh -> model -> continuation -> snap metrics (docs/physics.md sections 3-5).

``solve_scene`` is what ``snapjump curve`` and every sweep worker call. Everything is computed in
scaled units (lengths / R, stresses / mu of the inner or only cap) and converted back to SI here.
"""
from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from snapjump_cli.continuation import ContinuationFailed, ContinuationSettings, Path, Tracer, trace
from snapjump_cli.geometry import CapScene, Design, cap_volumes, design_volumes
from snapjump_cli.meshdata import Mesh
from snapjump_cli.metrics import (
    SnapTracker,
    constrained_instability,
    descend_at_volume,
    descent_starts,
    hermite_p_dV,
    path_self_crosses,
)
from snapjump_cli.lower_state import snap_at_fixed_volume
from snapjump_cli.model import Model
from snapjump_cli.settings import MeshSettings, SolverSettings

log = logging.getLogger(__name__)

__all__ = ["SolveFailed", "SceneResult", "solve_scene", "solve_design", "build_model", "warm_up"]


class SolveFailed(RuntimeError):
    """The continuation could not characterise the scene; the message gives the cause."""


@dataclass
class SceneResult:
    """Metrics (``metrics``, SI units, the stable keys) and the traced path (``curve``)."""

    metrics: dict
    curve: dict = field(default_factory=dict)
    model: Model | None = None
    path: Path | None = None
    states: object | None = None  # SnapStates
    tracer: Tracer | None = None


def _scales(scene: Design | CapScene) -> dict:
    """Scaled units and path-measure scales of a scene (all in scaled units except L, S)."""
    if isinstance(scene, Design):
        L, S, eta, th = scene.R_i, scene.mu_i, scene.eta_i, scene.theta_i
    else:
        L, S, eta, th = scene.R, scene.mu, scene.eta, scene.theta
    p_c = 4.0 / eta**2  # eq 14 with E = 3 mu, nu = 1/2, in units of mu
    sV = math.pi * math.sin(th) ** 2 / eta  # a cap-sized volume change (area x thickness)
    return {"L": L, "S": S, "p_c": p_c, "sV": sV, "sp": p_c, "sw": 1.0 / eta}


def build_model(scene: Design | CapScene, mesh: Mesh, solver: SolverSettings) -> Model:
    """The scaled FE model of a meshed scene."""
    sc = _scales(scene)
    if isinstance(scene, Design):
        mu = np.array([scene.mu_i, scene.mu_o])
        jm = np.array([scene.J_m, scene.J_m])
    else:
        mu = np.array([scene.mu, scene.mu])
        jm = np.array([scene.J_m, scene.J_m])
    return Model(mesh, mu, jm, solver.bulk_ratio, sc["L"], sc["S"])


def _V_stop(scene: Design | CapScene, V0_scaled: float) -> float:
    """Volume bound of the trace (scaled): 30 times the volume under the inner cap. Soft outer
    caps balloon far before the inner cap snaps (design D snaps at about 3 times that volume)."""
    if isinstance(scene, Design):
        under = math.pi / 3 * (1 - math.cos(scene.theta_i)) ** 2 * (2 + math.cos(scene.theta_i))
    else:
        under = math.pi / 3 * (1 - math.cos(scene.theta)) ** 2 * (2 + math.cos(scene.theta))
    return V0_scaled + 30.0 * under


def solve_scene(
    scene: Design | CapScene,
    mesh_settings: MeshSettings = MeshSettings(),
    solver: SolverSettings = SolverSettings(),
    mesh: Mesh | None = None,
) -> SceneResult:
    """Trace a scene's pressure-volume path and compute its snap metrics.

    Parameters
    ----------
    scene : a full actuator (:class:`Design`) or a single cap (:class:`CapScene`)
    mesh_settings, solver : mesh density and continuation settings
    mesh : a pre-built mesh (skips meshing)

    Returns
    -------
    SceneResult
        ``metrics`` holds the keys of :data:`snapjump_cli.settings.RESULT_KEYS` (SI units).

    Raises
    ------
    SolveFailed
        when the continuation fails before the snap is characterised.
    """
    from snapjump_cli.mesh import mesh_scene, solid_volumes

    t0 = time.perf_counter()
    if mesh is None:
        mesh = mesh_scene(scene, mesh_settings)
    t_mesh = time.perf_counter() - t0
    sc = _scales(scene)
    L, S = sc["L"], sc["S"]
    model = build_model(scene, mesh, solver)
    outer_alone = isinstance(scene, CapScene) and scene.kind == "outer"
    u0 = np.zeros(model.n)
    V0 = model.volume(u0)
    scales = (sc["sV"], sc["sp"], sc["sw"])
    cfg = ContinuationSettings(
        scales=scales, tol=solver.tol, ds0=solver.ds0 / 0.02 * 0.05, ds_max=solver.ds_max,
        max_steps=solver.max_steps, max_newton=solver.max_newton, max_turn_deg=solver.max_turn_deg,
        u_scale=solver.u_scale * sc["sw"], tol_path=solver.tol_path,
        fused=os.environ.get("SNAPJUMP_PROFILE_PHASES", "") != "1",
    )
    tracer = Tracer(model, cfg)
    if outer_alone:
        p_stop = 0.5  # E_o at p / mu_o = 0.5 (Fig. 3C)
    else:
        p_stop = 1.5 * sc["p_c"]
    tracker = SnapTracker(tracer, p_stop=p_stop, V_stop=_V_stop(scene, V0) / sc["sV"], full=solver.full)
    failure = ""
    path: Path | None = None
    try:
        path = trace(model, cfg, tracker, u0=u0, tracer=tracer)
    except ContinuationFailed as exc:
        failure = str(exc)
        path = getattr(exc, "path", None)
    st = tracker.states
    if path is None:
        raise SolveFailed(f"continuation failed: {failure}")

    # ---- quantities along the path ---------------------------------------------------------------
    pts = path.points
    sV, sp = sc["sV"], sc["sp"]
    pole1 = int(mesh.node_sets["pole_lower"][0])
    pole2 = int(mesh.node_sets["pole_upper"][0])

    def y_of(u, node):
        return model.positions(u)[node, 1] * L

    E_unit = S * L**3
    metrics: dict = {k: None for k in ("dE_J", "dE_norm", "dE_energy_J", "dE_path_J", "dE_rel_diff",
                                         "dy_pole_m", "dy_pole_upper_m", "dy_pole_norm", "p_star_Pa",
                                         "V_star_m3", "h_imp_m", "L0_m")}
    metrics["p_max_Pa"] = float(max(pt.p for pt in pts) * S)
    V_curve = np.array([pt.zeta[0] * sV for pt in pts])
    p_curve = np.array([pt.p for pt in pts])
    metrics["self_crossing"] = path_self_crosses(V_curve, p_curve)
    metrics["snaps"] = st.upper is not None
    lower_note = ""
    if st.upper is not None and st.lower is not None:
        lin = model.linearize(st.lower.u, st.lower.p)
        n_unstable = constrained_instability(tracer, lin) if lin is not None else 1
        if n_unstable > 0:
            lower_note = f"the path returned to V* on an unstable branch ({n_unstable} unstable modes)"
            st.lower, st.lower_method = None, ""
    if st.upper is not None and st.lower is None:
        why = lower_note or failure or path.stop_reason
        low, msg = snap_at_fixed_volume(tracer, st.upper)
        lower_solver = "volume-path"
        if low is None:
            log.debug("%s; falling back on the energy descent", msg)
            lower_solver = "energy-descent"
            # from the upper state along its unstable mode first; post-snap path points as fallbacks
            for start in [None] + descent_starts(pts, st.upper, st.k_before):
                low, msg = descend_at_volume(tracer, st.upper, start=start)
                if low is not None:
                    break
        if low is None:
            raise SolveFailed(f"volume limit found (V*={st.upper.zeta[0] * sV * L**3:.4g} m^3) but no lower state "
                              f"({why}; {msg})")
        st.lower, st.lower_method = low, "descent"
        metrics["lower_state_solver"] = lower_solver
        log.info("lower state at fixed volume (%s): %s", why, msg)
    metrics["lower_state_method"] = st.lower_method or None
    if st.upper is None and failure:
        exc = SolveFailed(f"no volume limit reached before the continuation failed: {failure}")
        exc.path, exc.model = path, model  # for diagnostics
        raise exc
    if outer_alone:
        metrics["E_o_J"] = _outer_energy(tracer, path, model, E_unit, sV, sp)
    if st.upper is not None:
        up, lo = st.upper, st.lower
        W_up, W_lo = model.energy(up.u), model.energy(lo.u)
        dE_energy = W_up - W_lo
        # path integral: upper -> points after it -> lower
        if st.lower_method == "path":
            k0, k1 = st.k_before, st.k_return
            seq = [up] + pts[k0 + 1 : k1] + [lo]
            integral = 0.0
            for a, b in zip(seq[:-1], seq[1:]):
                integral += hermite_p_dV(a, b, b.s - a.s, sV, sp)
            dE_path = -integral
        else:  # the descent state is not on the traced path: no path integral
            dE_path = float("nan")
            seq = [up, lo]
        metrics.update(
            dE_J=dE_energy * E_unit, dE_energy_J=dE_energy * E_unit,
            dE_path_J=dE_path * E_unit if math.isfinite(dE_path) else None,
            dE_rel_diff=abs(dE_energy - dE_path) / max(abs(dE_energy), 1e-300) if math.isfinite(dE_path) else None,
            dE_norm=dE_energy * E_unit / (S * L**3),
            p_star_Pa=up.p * S, V_star_m3=up.zeta[0] * sV * L**3,
            dy_pole_m=y_of(up.u, pole1) - y_of(lo.u, pole1),
            dy_pole_upper_m=y_of(up.u, pole2) - y_of(lo.u, pole2),
        )
        metrics["dy_pole_norm"] = metrics["dy_pole_m"] / L
        metrics["p_lower_Pa"] = lo.p * S
        snap_seq = seq if st.lower_method == "path" else [up, lo]
        if "ground" in mesh.node_sets and len(mesh.node_sets["ground"]):
            xg = model.positions(up.u)[mesh.node_sets["ground"], 1] * L
            metrics["h_imp_m"] = y_of(up.u, pole1) - float(xg.min())
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
        stop_reason=path.stop_reason, lower_state_note=lower_note, fold_note=st.fold_note, mesh_s=t_mesh,
        t_assembly_s=model.t_assembly, t_residual_s=model.t_residual, t_factor_s=model.t_factor,
        t_newton_s=model.t_newton,
        n_factorizations=model.n_factorizations, n_assemblies=model.n_assemblies,
        wall_s=time.perf_counter() - t0,
    )
    curve = {
        "p0_Pa": 0.0,
        "V0_m3": V0 * L**3,
        "L_m": L,
        "mu_Pa": S,
        "p_Pa": p_curve * S,
        "V_m3": V_curve * L**3,
        "y_pole_m": np.array([y_of(pt.u, pole1) for pt in pts]),
        "energy_J": np.array([model.energy(pt.u) for pt in pts]) * E_unit,
        "s": np.array([pt.s for pt in pts]),
    }
    if st.upper is not None:
        curve["snap_V_m3"] = np.array([pt.zeta[0] * sV for pt in snap_seq]) * L**3
        curve["snap_p_Pa"] = np.array([pt.p for pt in snap_seq]) * S
    return SceneResult(metrics=metrics, curve=curve, model=model, path=path, states=st, tracer=tracer)


def _outer_energy(tracer: Tracer, path: Path, model: Model, E_unit: float, sV: float, sp: float) -> float | None:
    """Stored energy of an outer cap alone at p / mu_o = 0.5 (state solved exactly at that p)."""
    pts = path.points
    for a, b in zip(pts[:-1], pts[1:]):
        if a.p < 0.5 <= b.p:
            w = (0.5 - a.p) / (b.p - a.p)
            res = tracer.correct((1 - w) * a.u + w * b.u, 0.5, None, None, 0.0, target=(1, 0.5 / sp))
            if res is None:
                return None
            return model.energy(res[0].u) * E_unit
    return None


#: A snap is re-solved at one mesh refinement when it is suspicious (see :func:`suspicious_snap`);
#: it is flagged ``mesh_sensitive`` when dE or dy_pole then move by more than this fraction.
MESH_SENSITIVE_REL = 0.05


_TIME_KEYS = ("wall_s", "mesh_s", "t_assembly_s", "t_residual_s", "t_factor_s", "t_newton_s")


def suspicious_snap(m: dict) -> str:
    """Why a snap may be a mesh artefact ('' if it looks sound): the pole moves up, the snap is
    tiny (dE < 1e-4 mu_i R_i^3), the volume limit is a near-cusp (``fold_note``: a bifurcation or a
    second pressure extremum right at the fold, where the branch can switch with the mesh), or its
    lower state had to be found by descent."""
    if not m.get("snaps"):
        return ""
    if m["dy_pole_m"] is None or m["dy_pole_m"] <= 0:
        return "pole moves up"
    if m["dE_norm"] < 1e-4:
        return "tiny snap"
    if m.get("fold_note"):
        return "volume limit at a near-cusp"
    if m.get("lower_state_method") == "descent":
        return "lower state by descent"
    return ""


def solve_design(
    design: Design, mesh: MeshSettings = MeshSettings(), solver: SolverSettings = SolverSettings(),
    check_mesh: bool = True,
) -> dict:
    """Sweep entry point: the metrics dict of one design (see :func:`solve_scene`).

    With ``check_mesh``, a suspicious snap (:func:`suspicious_snap`) is re-solved with one more
    element through the thickness (and, for a near-cusp fold, elements half as long along the arcs
    as well: the fold is an under-resolution of the arc, design A); the refined metrics are
    reported, the first ones kept as ``dE_J_coarse`` / ``dy_pole_m_coarse``, and ``mesh_sensitive``
    is set when dE or dy_pole moved by more than ``MESH_SENSITIVE_REL``, the refined run no longer
    snaps or fails, or its fold is still a near-cusp. For a re-solved design the timing keys
    (``wall_s``, ``mesh_s``, ``t_assembly_s``, ``t_residual_s``, ``t_factor_s``, ``t_newton_s``)
    cover both solves.
    """
    t0 = time.perf_counter()
    m = solve_scene(design, mesh, solver).metrics
    m.update(mesh_sensitive=False, dE_J_coarse=None, dy_pole_m_coarse=None, mesh_check="")
    why = suspicious_snap(m) if check_mesh else ""
    if not why:
        return m
    nt = mesh.nt + 1
    # element length along the arc ~ aspect * t / nt: halve it for a near-cusp, keep it otherwise
    aspect = mesh.aspect * nt / (2 * mesh.nt) if m.get("fold_note") else mesh.aspect
    finer = MeshSettings(order=mesh.order, nt=nt, aspect=aspect)
    coarse = m
    try:
        m = solve_scene(design, finer, solver).metrics
        m.update(mesh_sensitive=False, mesh_check=f"{why}; re-solved at nt={finer.nt}"
                 + (f", aspect={finer.aspect:.3g}" if finer.aspect != mesh.aspect else ""))
    except SolveFailed as exc:
        coarse["wall_s"] = time.perf_counter() - t0
        coarse["mesh_sensitive"] = True
        coarse["mesh_check"] = f"{why}; refined run failed: {exc}"
        return coarse
    m["dE_J_coarse"], m["dy_pole_m_coarse"] = coarse["dE_J"], coarse["dy_pole_m"]
    for k in _TIME_KEYS:  # the cost of the design is that of both solves
        m[k] = (m.get(k) or 0) + (coarse.get(k) or 0)
    if not m["snaps"]:
        m["mesh_sensitive"] = True
        return m
    if m.get("fold_note"):
        m["mesh_sensitive"] = True
        m["mesh_check"] += "; still a near-cusp"
    for k in ("dE_J", "dy_pole_m"):
        if abs(m[k] - coarse[k]) > MESH_SENSITIVE_REL * max(abs(m[k]), abs(coarse[k])):
            m["mesh_sensitive"] = True
    return m


def warm_up() -> float:
    """Compile (or load from the on-disk cache) every numba kernel; returns the seconds taken."""
    t0 = time.perf_counter()
    solve_scene(CapScene(theta_deg=60.0, eta=8.5, bc="clamped"), MeshSettings(order=1, nt=1, aspect=4.0),
                SolverSettings(max_steps=3))
    solve_scene(CapScene(theta_deg=60.0, eta=8.5, bc="clamped"), MeshSettings(order=2, nt=1, aspect=4.0),
                SolverSettings(max_steps=3))
    return time.perf_counter() - t0
