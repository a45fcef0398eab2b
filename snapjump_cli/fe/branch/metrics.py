"""The metrics of a followed branch: its snap in SI units and its curve for plots.

Definitions for a non-axisymmetric state: the *pole* is the material point on the axis (the
inner cap's lower pole, as for the axisymmetric metrics); every harmonic ``n >= 1`` vanishes on
the axis up to the ``n = 1`` translation across it, so its height is the axisymmetric part's. The
*ground* is the lowest point of the ring's bottom face over all phi (the actuator stands on it),
so ``h_imp`` is the pole's height above that point; the tilt of a free body (an exact symmetry)
is fixed by the gauge of harmonic 1 (:class:`~snapjump_cli.fe.branch.model.MultiHarmonicModel`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from snapjump_cli.fe.axisym.metrics import path_p_dV, snap_sequence
from snapjump_cli.fe.axisym.snap import SnapStates
from snapjump_cli.fe.branch.model import MultiHarmonicModel, component_index
from snapjump_cli.fe.continuation import Path

if TYPE_CHECKING:
    from snapjump_cli.fe.branch.trace import FollowResult

__all__ = ["branch_curve", "pole_height", "ground_height", "multiharmonic_snap_metrics"]


#: The note of a lower state found on the axisymmetric path (:func:`snapjump_cli.fe.branch.trace.axisym_landing`).
AXISYM_LANDING = "the axisymmetric path's state at that volume beyond its snap, stable with every harmonic kept"


#: The note of a lower state that is the axisymmetric solve's own lower state, found off its path, brought to the
#: branch's volume (:func:`snapjump_cli.fe.branch.trace.axisym_lower_landing`).
AXISYM_LOWER_LANDING = ("the axisymmetric lower state (found off the path) brought to that volume, stable with every "
                        "harmonic kept")


def branch_curve(fr: FollowResult) -> dict:
    """The followed branch in SI units for plots: ``V_m3``, ``p_Pa`` per traced point (from the
    bifurcation; for a branch that left another at a secondary bifurcation, that branch up to it
    first, and ``n_sec``, ``V_sec_m3``; for a jump off a branch, that branch up to the fold, and
    ``n_sec``, ``landing_V_m3``, ``landing_p_Pa``: the state it lands on) and, for a snap, ``snap_V_m3`` / ``snap_p_Pa`` (upper
    state, the branch after it, lower state; ``axisym_landing`` when the lower state is the
    axisymmetric path's, whose snap area lies under that path) and ``kind`` (that of the branch whose snap it is: the
    secondary branch's after a secondary bifurcation, where ``parent_kind`` is how the first branch
    left the axisymmetric path)."""
    mh, sc = fr.model, fr.tracer.sc
    L3, S = mh.L**3, mh.S
    pts = fr.path.points
    V = np.array([pt.zeta[0] * sc[0] for pt in pts]) * L3
    p = np.array([pt.p for pt in pts]) * S
    sec = fr.secondary
    jump = fr.kind == "jump"
    if fr.parent is not None and sec is not None:
        # the branch left behind: up to the secondary bifurcation, or (a jump) up to the fold, whose
        # state the jump's own path starts from
        head = fr.parent.path.points[: sec.index + 1] + ([] if jump else [sec.point])
        sp = fr.parent.tracer.sc
        V = np.concatenate([np.array([pt.zeta[0] * sp[0] for pt in head]) * L3, V])
        p = np.concatenate([np.array([pt.p for pt in head]) * S, p])
    parent_kind = (fr.parent.first_kind or fr.parent.kind) if fr.parent is not None else None
    out = {"V_m3": V, "p_Pa": p, "kind": fr.kind, "n": fr.bif.n, "N": int(mh.hn[-1]),
           "n_sec": sec.n if sec is not None else None,
           "V_sec_m3": sec.V_m3 if sec is not None and not jump else None,
           "parent_kind": parent_kind}
    if jump and sec is not None:  # the state the jump lands on, unstable outside the branch
        out["landing_V_m3"], out["landing_p_Pa"] = sec.V_m3, sec.p_Pa
    st = fr.states
    if st.upper is not None and st.lower is not None:
        seq = snap_sequence(fr.path, st)
        out["snap_V_m3"] = np.array([pt.zeta[0] * sc[0] for pt in seq]) * L3
        out["snap_p_Pa"] = np.array([pt.p for pt in seq]) * S
        # landed on the axisymmetric path's state (section 10.8): dE is the area under that path
        out["axisym_landing"] = fr.lower_note == AXISYM_LANDING
    return out


def pole_height(mh: MultiHarmonicModel, u: np.ndarray, node: int) -> float:
    return float(mh.section(u, 0.0)[node, 1])


def ground_height(mh: MultiHarmonicModel, u: np.ndarray, nodes: np.ndarray, n_phi: int = 720) -> float:
    """Lowest height of ``nodes`` over all phi (scaled): ``z + sum_k b_k cos n_k phi``."""
    A = mh.total_amplitudes(u)
    phi = np.linspace(0.0, 2.0 * np.pi, n_phi, endpoint=False)
    z = np.repeat(mh.X[nodes, 1][:, None], n_phi, axis=1)
    for k, n in enumerate(mh.hn):
        z += A[nodes, component_index(k, 1)][:, None] * np.cos(n * phi)[None, :]
    return float(z.min())


def multiharmonic_snap_metrics(mh: MultiHarmonicModel, path: Path, st: SnapStates, sc: np.ndarray) -> dict:
    """The snap metrics (SI) of a path of the multi-harmonic model with its upper and lower states
    (``{}`` without both): ``dE_J`` two ways, ``V_star_m3``, ``p_star_Pa``, ``dy_pole_m`` (the
    pole's travel along the axis), ``h_imp_m`` (the pole above the lowest point of the ground ring
    over all phi), ``L0_m``, and ``follow_amplitude_m`` (the largest harmonic amplitude ``n >= 1``
    at the upper state). Definitions: docs/harmonics.md section 10.2."""
    if st.upper is None or st.lower is None:
        return {}
    L, S = mh.L, mh.S
    E_unit = S * L**3
    out: dict = {}
    up, lo = st.upper, st.lower
    W_up, W_lo = mh.energy(up.u), mh.energy(lo.u)
    dE = W_up - W_lo
    dE_path = -path_p_dV(snap_sequence(path, st), sc[0], sc[1]) if st.lower_method == "path" else math.nan
    mesh = mh.mesh
    pole1 = int(mesh.node_sets["pole_lower"][0])
    out.update(
        dE_J=dE * E_unit, dE_energy_J=dE * E_unit,
        dE_path_J=dE_path * E_unit if math.isfinite(dE_path) else None,
        follow_dE_rel_diff=abs(dE - dE_path) / max(abs(dE), 1e-300) if math.isfinite(dE_path) else None,
        V_star_m3=float(up.zeta[0] * sc[0] * L**3), p_star_Pa=float(up.p * S),
        dy_pole_m=(pole_height(mh, up.u, pole1) - pole_height(mh, lo.u, pole1)) * L,
        p_lower_Pa=float(lo.p * S), dE_norm=dE, lower_state_method=st.lower_method or None,
    )
    out["dE_rel_diff"] = out["follow_dE_rel_diff"]
    out["dy_pole_norm"] = out["dy_pole_m"] / L
    nsets = mesh.node_sets
    if "pole_upper" in nsets:
        pole2 = int(nsets["pole_upper"][0])
        out["dy_pole_upper_m"] = (pole_height(mh, up.u, pole2) - pole_height(mh, lo.u, pole2)) * L
        if "outer_pole_lower" in nsets:
            z = mh.section(up.u, 0.0)[:, 1] * L
            out["L0_m"] = float(0.5 * (z[nsets["outer_pole_lower"][0]] + z[nsets["outer_pole_upper"][0]])
                                - 0.5 * (z[pole1] + z[pole2]))
    if "ground" in mesh.node_sets and len(mesh.node_sets["ground"]):
        g = np.asarray(mesh.node_sets["ground"], np.int64)
        out["h_imp_m"] = (pole_height(mh, up.u, pole1) - ground_height(mh, up.u, g)) * L
    # how far the branch is from axisymmetric at the upper state: the largest harmonic amplitude
    amp = 0.0
    for n in mh.hn[1:]:
        amp = max(amp, float(np.abs(mh.harmonic_part(up.u, int(n))).max()))
    out["follow_amplitude_m"] = amp * L
    return out
