"""Initial geometric imperfections: how sensitive is a design's snap to a moulding error?

A real actuator is not a perfect solid of revolution. This module gives the multi-harmonic model
(:class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel`) a stress-free reference that is the
perfect body displaced by a shape of harmonic ``n``, and traces the imperfect actuator from
rest to its snap under volume control. There is then no bifurcation to switch at: the path is
non-axisymmetric from the start and the snap is the volume limit of that path.

* **Shape** (:func:`imperfection_shape`): the lowest mode of the pencil ``(K_n, M_n)`` of the
  harmonic check. For a harmonic that goes unstable before ``V*`` it is the critical mode at the
  bifurcation; otherwise the mode of the path state before ``V*`` where the harmonic's margin
  (docs/harmonics.md section 11) is smallest, the mode nearest to going unstable.
* **Amplitude** ``delta``: the largest nodal displacement of the shape is ``delta`` times the inner
  cap's thickness (the only cap's, for a cap scene).
* **Trace** (:func:`trace_imperfect`): harmonics ``0, n, 2n, ... N`` (default ``4 n``), from the
  stress-free imperfect state with the continuation and snap tracker of the axisymmetric path;
  the lower state and the metrics as for a followed branch
  (:func:`snapjump_cli.fe.branch.metrics.multiharmonic_snap_metrics`).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from snapjump_cli.fe.continuation import ContinuationFailed, Path, Tracer, trace
from snapjump_cli.fe.branch.trace import BranchTracker, micro_energy, tracker_bounds
from snapjump_cli.fe.branch.bifurcation import default_harmonics, harmonic1_gauge, locate_bifurcation
from snapjump_cli.fe.stability.eigen import lowest_eigen
from snapjump_cli.fe.branch.metrics import multiharmonic_snap_metrics
from snapjump_cli.fe.stability.harmonics import harmonic_operator
from snapjump_cli.fe.axisym.lower_state import find_lower_state
from snapjump_cli.fe.branch.model import MultiHarmonicModel, component_index
from snapjump_cli.fe.axisym.snap import SnapStates

log = logging.getLogger(__name__)

__all__ = ["ImperfectionShape", "ImperfectResult", "imperfection_shape", "inner_thickness", "trace_imperfect"]


@dataclass
class ImperfectionShape:
    """A shape of harmonic ``n``: nodal ``(a, b, c)`` amplitudes ``(nn, 3)`` whose largest nodal
    displacement is 1 (scaled units), where it came from, and the path state it was taken at."""

    n: int
    mode: np.ndarray
    source: str  # "critical" (at the bifurcation) or "least stable" (smallest margin before V*)
    V: float  # scaled volume of the state it was taken at
    eig: float  # its (K_n, M_n) eigenvalue there (mu_min / L^2 of the scaled model)
    u: np.ndarray = field(repr=False, default=None)  # the axisymmetric state it was taken at


def _normalise(mode: np.ndarray) -> np.ndarray:
    size = float(np.sqrt((mode**2).sum(axis=1)).max())
    if not size > 0.0:
        raise ValueError("the mode is zero")
    return mode / size


def imperfection_shape(result, n: int) -> ImperfectionShape:
    """The imperfection shape of harmonic ``n`` for a solved scene ``result``
    (:class:`snapjump_cli.fe.solve.SceneResult`): the critical mode if ``n`` goes unstable before
    ``V*``, else the lowest mode at the path state before ``V*`` with the smallest eigenvalue."""
    if n < 1:
        raise ValueError(f"an imperfection needs a harmonic n >= 1, got {n}")
    bif = locate_bifurcation(result, n)
    if bif is not None:
        return ImperfectionShape(n, _normalise(bif.mode), "critical", float(bif.zeta[0]), float(bif.eig),
                                 np.array(bif.u))
    op = harmonic_operator(result.model, n)
    st = result.states
    pts = result.path.points[: st.k_before + 1] if st is not None and st.upper is not None else result.path.points
    best = None
    for pt in pts[1:]:
        ev = lowest_eigen(op, pt.u, pt.p)
        if ev is not None and (best is None or ev[0] < best[0]):
            best = (ev[0], ev[1], pt)
    if best is None:
        raise ValueError(f"no path state to take a mode of harmonic {n} from")
    eig, mode, pt = best
    return ImperfectionShape(n, _normalise(mode), "least stable", float(pt.zeta[0]), float(eig), np.array(pt.u))


def inner_thickness(scene) -> float:
    """The inner cap's thickness (the only cap's for a cap scene), in metres."""
    if hasattr(scene, "eta_i"):
        return float(scene.R_i / scene.eta_i)
    return float(scene.R / scene.eta)


@dataclass
class ImperfectResult:
    """An imperfect actuator traced from rest to its snap."""

    shape: ImperfectionShape
    delta: float
    model: MultiHarmonicModel
    path: Path
    states: SnapStates
    tracer: Tracer
    failure: str = ""
    lower_note: str = ""
    micro_folds: list = field(default_factory=list)
    metrics: dict = field(default_factory=dict)


def trace_imperfect(result, shape: ImperfectionShape, delta: float, thickness: float, N: int | None = None,
                    n_phi: int | None = None, micro: float = 1e-2, max_steps: int | None = None,
                    post_snap_steps: int | None = None) -> ImperfectResult:
    """Trace the actuator of ``result`` with the imperfection ``delta * thickness * shape`` from
    rest to its snap and lower state.

    Parameters
    ----------
    result : the perfect axisymmetric :class:`snapjump_cli.fe.solve.SceneResult`
    shape : :func:`imperfection_shape`'s answer
    delta : amplitude as a fraction of ``thickness`` (``>= 0``; 0 traces the perfect body, which
        stays on the axisymmetric path)
    thickness : the inner cap's thickness in metres (:func:`inner_thickness`)
    N, n_phi : harmonics ``0, n, ..., N`` (default ``4 n``) and the phi rule
    micro : a fold releasing less than this fraction of the perfect axisymmetric snap's energy is
        traced through (as on a followed branch)
    max_steps : bound on the continuation steps (default: the axisymmetric trace's)
    post_snap_steps : steps after the volume limit within which the path must come back to ``V*``
        (default: the axisymmetric trace's); beyond them the lower state is found at fixed volume

    Returns
    -------
    ImperfectResult
        with ``metrics``: those of :func:`snapjump_cli.fe.branch.metrics.multiharmonic_snap_metrics` and
        ``imp_n``, ``imp_delta``, ``imp_amplitude_m``, ``imp_shape``, ``imp_cpu_s``, ``imp_steps``,
        ``imp_stop`` (why the trace stopped), ``imp_note`` (says so when the path has no volume
        limit: the imperfect actuator then does not snap)
    """
    if not (delta >= 0.0 and math.isfinite(delta)):
        raise ValueError(f"the imperfection amplitude must be >= 0, got {delta}")
    t0 = time.process_time()
    base = result.model
    n = shape.n
    hn = default_harmonics(n, N)
    gauge = harmonic1_gauge(base, n, shape.u)
    nn = base.X.shape[0]
    nc = 2 + 3 * (len(hn) - 1)
    A_imp = np.zeros((nn, nc))
    o = component_index(1, 0)  # hn[1] = n
    amp = delta * thickness / base.L
    A_imp[:, o:o + 3] = amp * shape.mode
    mh = MultiHarmonicModel(base, hn, n_phi=n_phi, gauge=gauge, imperfection=A_imp)
    cfg = replace(result.tracer.cfg, fused=False, mixed_tangent=False)
    if max_steps is not None:
        cfg = replace(cfg, max_steps=int(max_steps))
    tr = Tracer(mh, cfg)
    p_stop, V_stop, post = tracker_bounds(result, post_snap_steps)
    tracker = BranchTracker(tr, p_stop=p_stop, V_stop=V_stop, post_snap_steps=post, kind="imperfect",
                            micro_dE=micro_energy(result, micro))
    failure = ""
    try:
        path = trace(mh, cfg, tracker, u0=np.zeros(mh.n), tracer=tr)
    except ContinuationFailed as exc:
        failure = str(exc)
        path = getattr(exc, "path", None) or Path(points=[])
    st = tracker.states
    out = ImperfectResult(shape, float(delta), mh, path, st, tr, failure=failure,
                          micro_folds=list(tracker.micro_folds))
    if st.upper is not None and path.points:
        low = find_lower_state(tr, st, path.points, failure or path.stop_reason)
        st.lower, st.lower_method = low.state, low.method
        out.lower_note = low.note or low.message
    m = multiharmonic_snap_metrics(mh, path, st, tr.sc)
    m.update(imp_n=n, imp_delta=float(delta), imp_amplitude_m=amp * base.L, imp_shape=shape.source,
             imp_steps=max(len(path.points) - 1, 0), imp_cpu_s=time.process_time() - t0,
             imp_micro_folds=len(out.micro_folds), imp_stop=path.stop_reason or None,
             imp_note="; ".join(x for x in (failure, out.lower_note, "" if st.upper is not None else
                                            f"no volume limit before the trace bound ({path.stop_reason})") if x))
    out.metrics = m
    log.debug("imperfection n=%d delta=%g: %s", n, delta, {k: m.get(k) for k in ("V_star_m3", "dE_J")})
    return out
