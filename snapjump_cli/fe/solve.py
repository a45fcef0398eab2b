"""One scene, end to end (docs/physics.md sections 3-5): mesh -> model -> trace -> lower state -> metrics.

``solve_scene`` is what ``snapjump curve`` and every sweep worker call; each stage has its module:
:mod:`snapjump_cli.mesh.build` (gmsh), :mod:`snapjump_cli.fe.axisym.model` (the problem interface),
:mod:`snapjump_cli.fe.continuation` with the stop criterion of :mod:`snapjump_cli.fe.axisym.snap` (the trace and
its upper state), :mod:`snapjump_cli.fe.axisym.lower_state` and :mod:`snapjump_cli.fe.axisym.metrics`. Everything is
computed in scaled units (lengths / R, stresses / mu of the inner or only cap) and converted back
to SI by the metrics. ``solve_design`` adds the mesh-sensitivity check of the sweep.
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from snapjump_cli.fe.axisym.air_snap import AirSnap, fluid_keys
from snapjump_cli.fe.continuation import ContinuationFailed, ContinuationSettings, Path, Tracer, trace
from snapjump_cli.fe.axisym.fluid import FluidSettings
from snapjump_cli.fe.limits import TimeLimitExceeded, time_limit
from snapjump_cli.geometry.caps import CapScene, Design
from snapjump_cli.fe.axisym.lower_state import find_lower_state
from snapjump_cli.mesh.data import Mesh
from snapjump_cli.fe.axisym.metrics import scene_curve, snap_metrics
from snapjump_cli.fe.axisym.model import Model
from snapjump_cli.schema import FOLLOWED, HARMONIC_CHECK, MARGINS, TIMING_KEYS, columns
from snapjump_cli.settings import MeshSettings, SolverSettings
from snapjump_cli.fe.axisym.snap import POST_SNAP_SKIPPED, SnapStates, SnapTracker, state_at_pressure

log = logging.getLogger(__name__)

__all__ = ["SolveFailed", "SceneResult", "solve_scene", "solve_checked", "solve_design", "build_model", "warm_up"]


class SolveFailed(RuntimeError):
    """The continuation could not characterise the scene; the message gives the cause."""


@dataclass
class SceneResult:
    """Metrics (``metrics``, SI units, the stable keys) and the traced path (``curve``, computed
    when first asked for: the sweep never needs it, and it costs an energy pass per path point)."""

    metrics: dict
    model: Model | None = None
    path: Path | None = None
    states: SnapStates | None = None
    tracer: Tracer | None = None
    curve_args: tuple | None = field(default=None, repr=False)  # (scales, V0) for :func:`scene_curve`
    stop_args: dict | None = field(default=None, repr=False)  # the snap tracker's bounds (p_stop, V_stop, ...)
    follow: object | None = field(default=None, repr=False)  # the followed branch (snapjump_cli.fe.branch.trace)
    margins: np.ndarray | None = field(default=None, repr=False)  # (states, 1 + harmonics): V and margins
    air: object | None = field(default=None, repr=False)  # the air snap (:class:`snapjump_cli.fe.axisym.air_snap.AirSnap`)
    lower: object | None = field(default=None, repr=False)  # how the lower state was found (LowerState)
    _curve: dict | None = field(default=None, init=False, repr=False)

    @property
    def curve(self) -> dict:
        """The traced path in SI units (:func:`snapjump_cli.fe.axisym.metrics.scene_curve`); ``{}`` without
        a path."""
        if self._curve is None:
            if self.curve_args is None or self.model is None or self.path is None:
                self._curve = {}
            else:
                self._curve = scene_curve(self.model, self.path, self.states, *self.curve_args)
                if self.air is not None:
                    self._curve.update(self.air.curve(self.model, self.path, *self.curve_args))
        return self._curve


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
    fluid: FluidSettings | None = None,
    *,
    fused: bool = True,
    post_snap: bool = True,
) -> SceneResult:
    """Trace a scene's pressure-volume path and compute its snap metrics.

    Parameters
    ----------
    scene : a full actuator (:class:`Design`) or a single cap (:class:`CapScene`)
    mesh_settings, solver : mesh density and continuation settings
    mesh : a pre-built mesh (skips meshing)
    fluid : water (``None``, the default) or air (:mod:`snapjump_cli.fe.axisym.air_snap`: the snap metrics
        are the air snap's, the water snap's are kept as ``water_dE_J``, ...)
    fused : the compiled Newton corrector (``False``: the Python corrector, whose timers split
        assembly and factorisation; the same answers, slower: for profiling)
    post_snap : trace the post-snap path (``False``: stop the trace once the upper state is located
        and the near-cusp watch has decided, :class:`~snapjump_cli.fe.axisym.snap.SnapTracker`; the lower
        state is then found at fixed volume unless the path was back at V* by then; the path's
        ``self_crossing``, ``n_steps`` and ``n_newton`` describe the shorter trace). Water only;
        ignored with ``solver.full``.

    Returns
    -------
    SceneResult
        ``metrics`` holds the keys of :data:`snapjump_cli.sweep.rows.RESULT_KEYS`, declared by :mod:`snapjump_cli.schema` (SI units).

    Raises
    ------
    SolveFailed
        when the continuation fails before the snap is characterised, or the mesh has more than
        ``solver.max_nodes`` nodes (then before it is solved).
    """
    from snapjump_cli.mesh.build import MeshTooLarge, mesh_scene  # lazily: gmsh

    t0 = time.perf_counter()
    try:
        if mesh is None:
            mesh = mesh_scene(scene, mesh_settings, max_nodes=solver.max_nodes)
        elif mesh.n_nodes > solver.max_nodes:
            raise MeshTooLarge(mesh.n_nodes, solver.max_nodes)
    except MeshTooLarge as exc:
        raise SolveFailed(f"not solved: {exc}") from None
    t_mesh = time.perf_counter() - t0
    sc = _scales(scene)
    scales = (sc["sV"], sc["sp"], sc["sw"])
    model = build_model(scene, mesh, solver)
    V0 = model.volume(np.zeros(model.n))
    air = None
    if fluid is not None and fluid.is_air:
        air = AirSnap(fluid, Tracer(model, _settings(scene, solver, fused)), post_snap_budget(solver))
    tracer, st, path, failure = _trace(scene, model, solver, V0, air, fused, post_snap=post_snap or air is not None)
    lower = find_lower_state(tracer, st, path.points, failure or path.stop_reason)
    if st.upper is not None and lower.state is None:
        raise SolveFailed(f"volume limit found (V*={st.upper.zeta[0] * sc['sV'] * sc['L']**3:.4g} m^3) but no lower "
                          f"state ({lower.reason}; {lower.message})")
    st.lower, st.lower_method = lower.state, lower.method
    if st.upper is None and failure:
        exc = SolveFailed(f"no volume limit reached before the continuation failed: {failure}")
        exc.path, exc.model = path, model  # for diagnostics
        raise exc
    outer_alone = isinstance(scene, CapScene) and scene.kind == "outer"
    metrics = snap_metrics(
        model, path, st, scales, lower_solver=lower.solver,
        lower_note=lower.note, outer_alone=outer_alone,
        outer_u=state_at_pressure(tracer, path, 0.5) if outer_alone else None,  # E_o at p / mu_o = 0.5 (Fig. 3C)
    )
    metrics.update(fluid_keys(fluid))
    if air is not None:
        air_lower = air.lower_state(path.points, failure or path.stop_reason)
        if air.states.upper is not None and air_lower.state is None:
            raise SolveFailed(f"limit of the dispensed volume found (p={air.states.upper.p * sc['S']:.5g} Pa) but no "
                              f"lower state under air ({air_lower.reason}; {air_lower.message})")
        metrics = air.metrics(model, path, metrics, air_lower, scales)
    metrics.update(
        mesh_s=t_mesh, t_assembly_s=model.t_assembly, t_residual_s=model.t_residual, t_factor_s=model.t_factor,
        t_newton_s=model.t_newton, n_factorizations=model.n_factorizations, n_assemblies=model.n_assemblies,
        wall_s=time.perf_counter() - t0,
    )
    stop_args = {"p_stop": tracer.stop_bounds[0], "V_stop": tracer.stop_bounds[1],
                 "post_snap_steps": post_snap_budget(solver)}
    return SceneResult(metrics=metrics, model=model, path=path, states=st, tracer=tracer, curve_args=(scales, V0),
                       air=air, stop_args=stop_args, lower=lower)


def post_snap_budget(solver: SolverSettings) -> int:
    """Steps the post-snap path may take to come back to V* before the lower state is sought at
    fixed volume instead: three quarters of ``max_steps`` (1500 at the default 2000), so that a
    finer trace, which needs a larger ``max_steps`` anyway, gets a proportionally larger budget
    (with a fixed 1500, a trace with 50x shorter steps ran out of it on the way back to V*)."""
    return max(1, (3 * solver.max_steps) // 4)


def _settings(scene: Design | CapScene, solver: SolverSettings, fused: bool = True) -> ContinuationSettings:
    """The continuation settings of a scene's trace."""
    sc = _scales(scene)
    return ContinuationSettings.from_solver(
        solver, scales=(sc["sV"], sc["sp"], sc["sw"]), u_unit=sc["sw"],
        fused=fused,
    )


def _trace(scene: Design | CapScene, model: Model, solver: SolverSettings, V0: float, air=None, fused: bool = True,
           post_snap: bool = True) -> tuple[Tracer, SnapStates, Path, str]:
    """Trace the scene's pressure-volume path from the stress-free state until the snap tracker
    (with ``air``, an :class:`~snapjump_cli.fe.axisym.air_snap.AirSnap`: until both snaps are characterised)
    stops it; returns the tracer, the snap states, the path and the continuation's failure ('' if
    none: a failed continuation keeps the path traced so far)."""
    sc = _scales(scene)
    cfg = _settings(scene, solver, fused)
    tracer = air.tracer if air is not None else Tracer(model, cfg)
    if isinstance(scene, CapScene) and scene.kind == "outer":
        p_stop = 0.5  # E_o at p / mu_o = 0.5 (Fig. 3C)
    else:
        p_stop = 1.5 * sc["p_c"]
    tracker = SnapTracker(tracer, p_stop=p_stop, V_stop=_V_stop(scene, V0) / sc["sV"], full=solver.full,
                          post_snap_steps=post_snap_budget(solver), post_snap=post_snap)
    tracer.stop_bounds = (tracker.p_stop, tracker.V_stop)
    failure = ""
    path: Path | None = None
    try:
        path = trace(model, cfg, tracker if air is None else air.watch(tracker), u0=np.zeros(model.n), tracer=tracer)
    except ContinuationFailed as exc:
        failure = str(exc)
        path = getattr(exc, "path", None)
    if path is None:
        raise SolveFailed(f"continuation failed: {failure}")
    return tracer, tracker.states, path, failure


#: A snap is re-solved at one mesh refinement when it is suspicious (see :func:`suspicious_snap`);
#: it is flagged ``mesh_sensitive`` when dE or dy_pole then move by more than this fraction.
MESH_SENSITIVE_REL = 0.05


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


def solve_checked(
    scene: Design | CapScene, mesh: MeshSettings = MeshSettings(), solver: SolverSettings = SolverSettings(),
    check_mesh: bool = True, fluid: FluidSettings | None = None, *, fused: bool = True, short_recheck: bool = False,
) -> SceneResult:
    """Solve a scene the way every command reports it: :func:`solve_scene`, the mesh check, and
    (``solver.harmonics > 0``) the Fourier-harmonic stability check of the reported solve
    (:func:`snapjump_cli.fe.stability.harmonics.check_harmonics`: ``asym_first``, ``asym_n``, ``asym_V_m3``,
    ``asym_p_Pa``, ``asym_lower_stable``; all None when it is off). ``fluid``: water (``None``) or
    air (:func:`solve_scene`; not with the harmonic check); ``fused`` as in :func:`solve_scene`.
    ``short_recheck``: the mesh re-check of a design whose coarse path went to zero volume stops
    its trace at the snap (:func:`_short_recheck`; the sweep's :func:`solve_design` asks for it,
    ``snapjump curve`` does not: it draws the re-checked path).

    All of it runs within ``solver.time_limit_s`` CPU seconds (:mod:`snapjump_cli.fe.limits`);
    beyond them :class:`SolveFailed` says so.
    """
    if fluid is not None and fluid.is_air and solver.harmonics > 0:
        raise ValueError("the harmonic check is not available under air (fluid: air with solver.harmonics > 0)")
    try:
        with time_limit(solver.time_limit_s):
            return _solve_and_check(scene, mesh, solver, check_mesh, fluid, fused, short_recheck)
    except TimeLimitExceeded as exc:
        raise SolveFailed(f"stopped: {exc}") from None


def _solve_and_check(scene: Design | CapScene, mesh: MeshSettings, solver: SolverSettings, check_mesh: bool,
                     fluid: FluidSettings | None, fused: bool, short_recheck: bool = False) -> SceneResult:
    checked: dict = {}  # the harmonic check of a solve, made before the mesh re-check (followed solves)

    def check(res: SceneResult):
        from snapjump_cli.fe.stability.harmonics import check_harmonics

        if checked.get("result") is not res:
            t0 = time.perf_counter()
            checked.update(result=res, check=check_harmonics(res, solver.harmonics), wall=time.perf_counter() - t0)
        return checked["check"], checked["wall"]

    def goes_asymmetric_first(res: SceneResult) -> str:
        if res.model is None or res.path is None:
            return ""
        h, _ = check(res)
        return f"not re-checked: harmonic {h.asym_n} goes unstable first (the actuator does not make this snap)" \
            if h.asym_first else ""
    skip = goes_asymmetric_first if solver.follow and solver.harmonics > 0 else None
    res = _solve_mesh_checked(scene, mesh, solver, check_mesh, fluid, fused, short_recheck, skip_recheck=skip)
    m = res.metrics
    m.update({k: None for k in columns(HARMONIC_CHECK)})
    m.update({k: None for k in columns(FOLLOWED)})
    m.update({k: None for k in columns(MARGINS)})
    if checked and checked["result"] is not res:  # (the check of the solve the re-check replaced)
        m["wall_s"] = (m.get("wall_s") or 0.0) + checked["wall"]
    if solver.harmonics > 0 and res.model is not None and res.path is not None:
        h, m["asym_wall_s"] = check(res)
        m.update(h.as_row())
        m["wall_s"] = (m.get("wall_s") or 0.0) + m["asym_wall_s"]
        if solver.margins:
            from snapjump_cli.fe.stability.margins import path_margins

            margins = path_margins(res, solver.harmonics)
            res.margins = margins.table
            m.update(margins.as_row())
        if solver.follow:
            from snapjump_cli.fe.branch.followed import apply_followed

            apply_followed(res, h, solver.follow_N, mode=solver.follow_mode)
    return res


def _solve_mesh_checked(
    scene: Design | CapScene, mesh: MeshSettings, solver: SolverSettings, check_mesh: bool,
    fluid: FluidSettings | None = None, fused: bool = True, short_recheck: bool = False,
    skip_recheck: Callable[[SceneResult], str] | None = None,
) -> SceneResult:
    """:func:`solve_scene`, then the mesh check.

    With ``check_mesh``, a suspicious snap (:func:`suspicious_snap`) is re-solved with one more
    element through the thickness (and, for a near-cusp fold, elements half as long along the arcs
    as well: the fold is an under-resolution of the arc, design A); the refined solve is reported,
    the first metrics kept as ``dE_J_coarse`` / ``dy_pole_m_coarse``, and ``mesh_sensitive`` is set
    when dE or dy_pole moved by more than ``MESH_SENSITIVE_REL``, the refined run no longer snaps
    or fails, or its fold is still a near-cusp; ``mesh_check`` says why and how it was checked. For
    a re-solved scene the timing keys (``wall_s``, ``mesh_s``, ``t_assembly_s``, ``t_residual_s``,
    ``t_factor_s``, ``t_newton_s``) cover both solves. With ``short_recheck`` the re-check of a
    design whose coarse path went to zero volume stops its trace at the snap (:func:`_short_recheck`).
    ``skip_recheck(result)``: a reason not to re-solve a suspicious snap (``""``: re-solve it); a
    followed solve passes the harmonic check, so that the snap of a design that goes asymmetric
    first, which its actuator does not make, is not re-solved (``mesh_check`` then says so).

    Returns
    -------
    SceneResult
        The reported solve (the refined one after a re-solve), its ``metrics`` completed with
        ``mesh_sensitive``, ``mesh_check``, ``dE_J_coarse`` and ``dy_pole_m_coarse``.
    """
    t0 = time.perf_counter()
    air = {"fluid": fluid} if fluid is not None and fluid.is_air else {}
    if not fused:
        air["fused"] = False
    res = solve_scene(scene, mesh, solver, **air)
    m = res.metrics
    m.update(mesh_sensitive=False, dE_J_coarse=None, dy_pole_m_coarse=None, mesh_check="")
    why = suspicious_snap(m) if check_mesh else ""
    if not why:
        return res
    skip = skip_recheck(res) if skip_recheck is not None else ""
    if skip:
        m["mesh_check"] = f"{why}; {skip}"
        return res
    nt = mesh.nt + 1
    # element length along the arc ~ aspect * t / nt: halve it for a near-cusp, keep it otherwise
    aspect = mesh.aspect * nt / (2 * mesh.nt) if m.get("fold_note") else mesh.aspect
    finer = MeshSettings(order=mesh.order, nt=nt, aspect=aspect)
    coarse = m
    short = short_recheck and _short_recheck(coarse, solver, air)
    try:
        fine, spent = None, 0.0
        if short:
            t1 = time.perf_counter()
            try:
                fine = solve_scene(scene, finer, solver, **air, post_snap=False)
            except SolveFailed:  # (no lower state at fixed volume: the full trace has more to try)
                pass
            if fine is None or not _short_recheck_holds(fine):
                short, fine = False, None  # solved again with the whole trace
                spent = time.perf_counter() - t1
        if fine is None:
            fine = solve_scene(scene, finer, solver, **air)
        res = fine
        m = res.metrics
        m["wall_s"] = (m.get("wall_s") or 0.0) + spent
        m.update(mesh_sensitive=False, mesh_check=f"{why}; re-solved at nt={finer.nt}"
                 + (f", aspect={finer.aspect:.3g}" if finer.aspect != mesh.aspect else ""))
        if short and m.get("stop_reason") == POST_SNAP_SKIPPED:  # (else it was back at V* before it stopped)
            m["self_crossing"] = bool(m["self_crossing"] or coarse.get("self_crossing"))
            m["mesh_check"] += f" to the snap (post-snap path and self_crossing: nt={mesh.nt})"
    except SolveFailed as exc:
        coarse["wall_s"] = time.perf_counter() - t0
        coarse["mesh_sensitive"] = True
        coarse["mesh_check"] = f"{why}; refined run failed: {exc}"
        return res
    m["dE_J_coarse"], m["dy_pole_m_coarse"] = coarse["dE_J"], coarse["dy_pole_m"]
    for k in TIMING_KEYS:  # the cost of the design is that of both solves
        m[k] = (m.get(k) or 0) + (coarse.get(k) or 0)
    if not m["snaps"]:
        m["mesh_sensitive"] = True
        return res
    if m.get("fold_note"):
        m["mesh_sensitive"] = True
        m["mesh_check"] += "; still a near-cusp"
    for k in ("dE_J", "dy_pole_m"):
        if abs(m[k] - coarse[k]) > MESH_SENSITIVE_REL * max(abs(m[k]), abs(coarse[k])):
            m["mesh_sensitive"] = True
    return res


#: The stop reasons of a coarse trace that followed the post-snap path to its end without coming
#: back to V* (the cavity volume at zero): the re-check of such a design need not trace it again.
_POST_SNAP_ENDS = ("cavity volume reached zero",)


def _short_recheck(coarse: dict, solver: SolverSettings, air: dict) -> bool:
    """Whether the mesh re-check of a design may stop its trace at the upper state
    (``solve_scene(..., post_snap=False)``): its coarse path went to zero cavity volume without
    coming back to V* (the lower state by descent), under water, without ``solver.full``.

    The re-check exists for the snap's answers, which come from the upper state and the lower
    state at fixed volume (``lower_state_method = "descent"``); neither depends on the post-snap
    path. That path (150-190 steps to zero volume at nt 3, ~40 % of such a design's CPU) fed only
    the ``self_crossing`` flag, ``n_steps`` and ``n_newton`` of the reported row; the flag is then
    taken from the coarse path (which was traced to its end) or'ed with the refined trace's own
    (docs/performance.md: on the paper grid it differed between the two meshes on 2 of 465 designs).
    """
    return (not air and not solver.full and coarse.get("lower_state_method") == "descent"
            and coarse.get("stop_reason") in _POST_SNAP_ENDS)


def _short_recheck_holds(res: SceneResult) -> bool:
    """Whether a re-check stopped at the upper state gave what the full trace would (else it is
    solved again with the whole trace): its lower state was found without the post-snap path (on
    the path before the trace stopped, by the volume path or by the energy descent along the fold's
    unstable mode, which start from the upper state alone, ``LowerState.from_path``), or there is
    no snap."""
    if not res.metrics.get("snaps"):
        return True
    lower = res.lower
    return lower is not None and not lower.from_path


def solve_design(
    design: Design, mesh: MeshSettings = MeshSettings(), solver: SolverSettings = SolverSettings(),
    check_mesh: bool = True, fluid: FluidSettings | None = None, *, fused: bool = True,
) -> dict:
    """Sweep entry point: the metrics dict of one design as :func:`solve_checked` reports it, with
    the short mesh re-check (``short_recheck``: the sweep does not keep the traced path; ``fused``:
    as in :func:`solve_scene`)."""
    return solve_checked(design, mesh, solver, check_mesh, fluid=fluid, fused=fused, short_recheck=True).metrics


def warm_up() -> float:
    """Compile (or load from the on-disk cache) every numba kernel; returns the seconds taken."""
    t0 = time.perf_counter()
    solve_scene(CapScene(theta_deg=60.0, eta=8.5, bc="clamped"), MeshSettings(order=1, nt=1, aspect=4.0),
                SolverSettings(max_steps=3))
    solve_scene(CapScene(theta_deg=60.0, eta=8.5, bc="clamped"), MeshSettings(order=2, nt=1, aspect=4.0),
                SolverSettings(max_steps=3))
    return time.perf_counter() - t0
