"""The design's answer with its followed branch: the one module that sees both the branch's trace
(:mod:`snapjump_cli.fe.branch.trace`) and its secondary bifurcations
(:mod:`snapjump_cli.fe.branch.secondary`) (docs/harmonics.md, section 10).

:func:`followed_metrics` locates the bifurcation of the first unstable harmonic, follows its
branch to its snap and, for a branch that keeps only multiples of ``n_c >= 2``, the branch that
leaves it where it loses stability to the other harmonics first (:func:`leave_at_secondary`);
:func:`apply_followed` makes that snap the design's answer (the keys of
:data:`snapjump_cli.schema.FOLLOWED`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from snapjump_cli.fe.branch.bifurcation import default_harmonics, first_bifurcation, locate_bifurcation
from snapjump_cli.fe.branch.secondary import follow_secondary, leaves_branch, stability_watch, stable_outside
from snapjump_cli.fe.branch.trace import MICRO_FOLD_DE, UNSTABLE_OUTSIDE, FollowResult, follow_branch
from snapjump_cli.fe.limits import TimeLimitExceeded
from snapjump_cli.schema import FOLLOWED, keys

if TYPE_CHECKING:
    from snapjump_cli.fe.stability.harmonics import HarmonicCheck

__all__ = ["FOLLOW_MODES", "AXISYM_FIRST_ALL", "WATCH_THROUGH_FOLDS", "first_secondary", "record_secondary",
           "FOLLOW_KEYS", "REPLACED_KEYS", "FollowedAnswer", "axisym_answer", "followed_metrics", "leave_at_secondary",
           "apply_followed"]

#: How a branch is followed (:func:`followed_metrics`): ``"actuator"`` (the default: only the
#: states the actuator passes through before a secondary bifurcation are traced) or ``"full"``
#: (the reference: the whole branch to its snap, then the check).
FOLLOW_MODES: tuple[str, ...] = ("actuator", "full")

#: The actuator mode lands a branch of ``n_c >= 2`` that loses no stability outside its harmonics
#: first and loops back to the axisymmetric path without a lower state on the axisymmetric inverted
#: state at its volume limit, where that state is stable with every harmonic ``0..N``, before the
#: search at fixed volume (``False``: the search, as the reference; a switch for measurements).
AXISYM_FIRST_ALL = True

#: The actuator mode watches the trace of a branch of ``n_c >= 2`` that goes on past a fold at or
#: near its bifurcation (one that releases almost nothing, or a micro-fold whose landing the actuator
#: stays on) for the first state unstable outside its harmonics, and stops there, as the trace up to
#: the first volume limit (:func:`first_secondary`) does; ``False``: such a branch is traced to its
#: snap (and its lower state searched) before the check, as before. On grid rows 3070, 3112,
#: 3128, 3144, 3176, 3192, 3756 and 4414 of ``configs/paper_grid_followed.yaml`` (a branch that rises
#: by a few 1e-7 and folds at its bifurcation, then loses stability to harmonic 1): 2.7-3.4x less
#: CPU, the answers bit for bit (docs/harmonics.md section 10.7 has the command); the samples
#: ``follow_strata`` and ``follow_strata_n2`` bit for bit.
WATCH_THROUGH_FOLDS = True

#: Keys :func:`followed_metrics` adds to a design's metrics (SI units): the followed stage's keys
#: of :data:`snapjump_cli.schema.FOLLOWED`, columns and diagnostics.
FOLLOW_KEYS: tuple[str, ...] = keys(FOLLOWED)


#: The row keys a followed answer replaces (the axisymmetric values of the first five stay in
#: ``axisym_*``).
REPLACED_KEYS: tuple[str, ...] = (
    "dE_J", "dE_norm", "dE_energy_J", "dE_path_J", "dE_rel_diff", "dy_pole_m", "dy_pole_norm", "dy_pole_upper_m",
    "h_imp_m", "V_star_m3", "p_star_Pa", "p_lower_Pa", "L0_m", "lower_state_method")


@dataclass
class FollowedAnswer:
    """The design's answer with its followed branch (:func:`followed_metrics`): ``values``, the keys
    of :data:`FOLLOW_KEYS` and, for a branch traced to a snap, that snap's metrics (SI units);
    ``branch``, the followed branch (``None`` when none was traced)."""

    values: dict
    branch: FollowResult | None = None

    @property
    def followed(self) -> bool:
        """Whether the followed snap is the design's answer."""
        return bool(self.values.get("followed"))

    def as_row(self) -> dict:
        """What the answer sets in the design's metrics: the keys of :data:`FOLLOW_KEYS`,
        ``follow_amplitude_m`` and, for a followed answer, the :data:`REPLACED_KEYS` of the
        followed snap."""
        row = {k: self.values.get(k) for k in FOLLOW_KEYS}
        row["follow_amplitude_m"] = self.values.get("follow_amplitude_m")
        if self.values["followed"]:
            row.update({k: self.values[k] for k in REPLACED_KEYS if k in self.values})
        return row


def axisym_answer(m: dict, note: str = "") -> dict:
    """The follow keys of a design that keeps its axisymmetric answer (``m``: its metrics)."""
    out = {k: None for k in FOLLOW_KEYS}
    out.update({"axisym_" + k: m.get(k) for k in ("dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa")})
    out.update(followed=False, follow_note=note)
    return out


def followed_metrics(result, check: HarmonicCheck, N: int | None = None, n_phi: int | None = None,
                     secondary: bool = True, mode: str = "actuator") -> FollowedAnswer:
    """The design's answer with the followed branch (the keys of :data:`FOLLOW_KEYS` and the
    followed ``dE_J``, ``dy_pole_m``, ``h_imp_m``, ``V_star_m3``, ``p_star_Pa``), given the
    axisymmetric ``result`` and its harmonic ``check``.

    A design whose check finds no harmonic unstable before ``V*`` keeps its axisymmetric answer
    (``followed`` False, the two sets equal). Otherwise the branch of the first unstable harmonic
    is traced; if it cannot be followed to a snap the axisymmetric answer is kept and
    ``follow_note`` says why. With ``secondary``, a branch that keeps only multiples of
    ``n_c >= 2`` is checked against the other harmonics up to its snap
    (:func:`snapjump_cli.fe.branch.secondary.follow_secondary`); where it loses stability to them first,
    the branch that leaves it there is traced with every harmonic and its snap is the answer
    (``follow_sec_n``, ``follow_sec_V_m3``).

    ``mode``: ``"actuator"`` traces such a branch only up to its first volume limit before the
    check (:func:`first_secondary`): when it loses stability to the other harmonics before it, as
    most such branches do, its fold, the branch beyond it and its lower state are never needed;
    otherwise it is traced on as in ``"full"`` (the reference), which traces the whole branch
    to its snap before the check. Both give the same answer. For a branch of ``n_c = 1`` (every
    harmonic ``0..N`` kept), ``"actuator"`` also lands a subcritical snap on the axisymmetric
    path's inverted state at the bifurcation's volume without tracing the branch, where that state
    is stable with every harmonic (and, for a branch that loops back to the axisymmetric path,
    takes it before searching at fixed volume): ``landing="axisymmetric first"`` of
    :func:`snapjump_cli.fe.branch.trace.trace_branch`; ``"full"`` traces and searches (the
    reference the samples check it against: docs/harmonics.md, "Where the actuator lands").
    """
    if mode not in FOLLOW_MODES:
        raise ValueError(f"follow mode must be one of {FOLLOW_MODES}, got {mode!r}")
    m = result.metrics
    out = axisym_answer(m)
    if not check.asym_first or result.states is None or result.states.upper is None:
        return FollowedAnswer(out)
    t0 = time.perf_counter()
    n = int(check.asym_n)
    # every harmonic the check found unstable at its first unstable state: the first one located
    ns = [int(x) for x in str(check.asym_ns or n).split(",") if x.strip()]
    bif = first_bifurcation(result, ns) if len(ns) > 1 else locate_bifurcation(result, n)
    if bif is None:
        out["follow_note"] = f"bifurcation of harmonic {n} not located"
        return FollowedAnswer(out)
    note_first = ""
    if bif.n != n:
        note_first = (f"harmonic {bif.n} bifurcates before harmonic {n} (both unstable at the harmonic check's "
                      f"first unstable state): its branch is followed")
        n = bif.n
    hn = default_harmonics(n, N)
    # (a branch of n_c >= 2 keeps only multiples of n_c: a state stable there may not be stable)
    landing = "axisymmetric first" if mode == "actuator" and len(hn) > 1 and int(hn[1]) == 1 else "search"
    # a branch of n_c >= 2 that loops back: the axisymmetric inverted state first, checked with every harmonic
    even_first = mode == "actuator" and secondary and AXISYM_FIRST_ALL and len(hn) > 1 and int(hn[1]) > 1
    vp = mode == "full"  # the actuator mode searches by the energy descent alone (section 10.8)
    # a subcritical secondary branch: the actuator mode descends from its bifurcation before tracing it
    # a jump off a branch of n_c >= 2: the actuator mode lands it by the sphere path first
    sec_kw = {"volume_path": vp, "landing": "descent first" if mode == "actuator" else "search",
              "jump_path": mode == "actuator"}
    fr, note_sec = None, ""
    checked = secondary and mode == "actuator" and len(hn) > 1 and int(hn[1]) > 1
    if checked:
        fr, note_sec = first_secondary(result, bif, hn, n_phi, **sec_kw)
    if fr is None:
        # the actuator mode does not trace a branch of n_c >= 2 on past a micro-fold whose landing it
        # leaves at once (unstable outside the branch: the jump goes on, leave_at_secondary), nor
        # past its first state unstable outside it (the watch: as first_secondary's, through folds)
        settle = leaves_branch(u_axi=bif.u) if checked else None
        check = stable_outside(u_axi=bif.u) if even_first else None
        def trace(watch=None) -> FollowResult:
            return follow_branch(result, bif, hn, n_phi=n_phi, landing=landing, volume_path=vp, settle=settle,
                                 landing_check=check, watch=watch)

        fr = trace(stability_watch(u_axi=bif.u) if checked and WATCH_THROUGH_FOLDS else None)
        if secondary and len(fr.model.hn) > 1 and int(fr.model.hn[1]) > 1:
            watched = fr
            fr, note_sec = leave_at_secondary(result, fr, **sec_kw)
            if fr is watched and watched.path.stop_reason == UNSTABLE_OUTSIDE:
                # the watch stopped the trace where the check finds no secondary bifurcation to leave
                # by: the branch traced on to its snap without the watch (WATCH_THROUGH_FOLDS off)
                fr, note_sec = leave_at_secondary(result, trace(), **sec_kw)
    fm = fr.metrics
    out.update({k: v for k, v in fm.items() if k in FOLLOW_KEYS})
    if note_sec or note_first:
        out["follow_note"] = "; ".join(x for x in (note_first, note_sec, out.get("follow_note")) if x)
    if fm.get("dE_J") is None:
        out["follow_note"] = out.get("follow_note") or "the followed branch did not reach a snap"
        out["follow_wall_s"] = time.perf_counter() - t0
        return FollowedAnswer(out, fr)
    dE_axi = m.get("dE_J")
    if dE_axi and fm["dE_J"] < MICRO_FOLD_DE * dE_axi:
        # a fold whose lower state was found off the branch (so the tracker could not trace through
        # it) and that releases almost nothing: the actuator goes on along the branch to a later
        # snap that was not traced, so this is not the design's answer
        out["follow_note"] = "; ".join(x for x in (out.get("follow_note"), (
            f"the branch's first fold releases {fm['dE_J']:.3g} J, < {MICRO_FOLD_DE:g} of the axisymmetric "
            "dE: not the snap, and the branch beyond it was not traced")) if x)
        out["follow_wall_s"] = time.perf_counter() - t0
        return FollowedAnswer(out, fr)
    if fm.get("dy_pole_m") is not None and not fm["dy_pole_m"] > 0.0:
        # the pole moves up in the followed snap: no jump the mass-spring model can describe (a sweep
        # row with it fails its range check and would lose the axisymmetric answer as well)
        out["follow_note"] = "; ".join(x for x in (out.get("follow_note"), (
            f"the followed snap moves the pole up (dy_pole {fm['dy_pole_m']:.3g} m, dE {fm['dE_J']:.3g} J): "
            "not used as the answer")) if x)
        out["follow_wall_s"] = time.perf_counter() - t0
        return FollowedAnswer(out, fr)
    out["followed"] = True
    for k in fm:
        if k not in out or k in REPLACED_KEYS:
            out[k] = fm[k]
    out["follow_wall_s"] = time.perf_counter() - t0
    return FollowedAnswer(out, fr)


def first_secondary(result, bif, hn: list[int], n_phi: int | None = None,
                    **kw) -> tuple[FollowResult | None, str]:
    """The branch leaving a secondary bifurcation that the branch of ``bif`` (harmonics ``hn``, a
    multiple of ``n_c >= 2``) meets before its first volume limit, traced up to that limit only;
    ``(None, "")`` when there is none there (the branch must then be traced to its snap:
    :func:`leave_at_secondary`). The states checked, the point located and the branch leaving it
    are those of the full trace, which passes through the same states first. ``kw``: how the
    branch leaving the secondary bifurcation finds its lower state (``volume_path``, ``landing``
    of :func:`snapjump_cli.fe.branch.trace.trace_branch`)."""
    # checked while traced: the trace stops at the first checked state unstable outside the branch
    head = follow_branch(result, bif, hn, n_phi=n_phi, stop_at_upper=True, watch=stability_watch(u_axi=bif.u))
    if head.states.upper is None and head.path.stop_reason != UNSTABLE_OUTSIDE:
        return None, ""
    fs, chk, sec = follow_secondary(result, head, **kw)
    if sec is None or fs is None:
        return None, ""
    return fs, record_secondary(fs, chk, sec, bif.n)


def record_secondary(fs: FollowResult, chk, sec, n: int) -> str:
    """Record on ``fs`` (its ``follow_sec_*`` metrics) that the followed answer left its branch of
    harmonic ``n`` at the secondary bifurcation ``sec``, and return the answer's note."""
    fs.metrics.update(follow_sec_n=sec.n, follow_sec_V_m3=sec.V_m3, follow_sec_p_Pa=sec.p_Pa)
    if fs.kind == "jump":
        plane = f" (symmetric about phi = pi/{n})" if getattr(fs.parent, "turned", False) else ""
        how = {"volume-path": "fixed-volume path", "sphere-path": "sphere path"}.get(fs.lower_solver, "energy descent")
        to = (f"the axisymmetric inverted state, stable with every harmonic 0-{chk.N}"
              if fs.lower_solver == "axisymmetric path" else f"a state with every harmonic 0-{chk.N} ({how})")
        return (f"the branch of harmonic {n} folds at V = {fs.metrics.get('V_star_m3') or math.nan:.4g} m^3 and "
                f"the state it jumps to on the branch is unstable in harmonic {sec.n}{plane}: the jump goes on, at "
                f"that volume, to {to}")
    plane = f" (symmetric about phi = pi/{n})" if getattr(fs.parent, "turned", False) else ""
    return (f"the branch of harmonic {n} loses stability to harmonic {sec.n}{plane} at V = {sec.V_m3:.4g} m^3, "
            f"before its own snap: the branch that leaves it there is traced with harmonics 0-{chk.N}")


def leave_at_secondary(result, fr: FollowResult, **kw) -> tuple[FollowResult, str]:
    """The branch the actuator takes when the followed branch ``fr`` loses stability outside its
    harmonics before its snap (:func:`snapjump_cli.fe.branch.secondary.follow_secondary`), with a note;
    ``fr`` itself (and no note) when it does not. A secondary branch that cannot be traced to a
    snap is returned all the same: the design then keeps its axisymmetric answer. ``kw`` as for
    :func:`first_secondary`."""
    fs, chk, sec = follow_secondary(result, fr, **kw)
    if chk.first is None:
        return fr, ""
    n = fr.bif.n
    if sec is None:
        V1 = chk.first_V_m3 if chk.first_V_m3 is not None else chk.V_m3[chk.first]
        fr.metrics.update(dE_J=None, follow_sec_V_m3=V1)
        return fr, (f"the branch of harmonic {n} is unstable outside its harmonics at V = {V1:.4g} m^3 "
                    f"(harmonics up to {chk.N}) and no secondary bifurcation was located before it (the actuator "
                    "may reach that state by a jump past a fold of the branch): not traced further")
    return fs, record_secondary(fs, chk, sec, n)


def apply_followed(result, check: HarmonicCheck, N: int = 0, mode: str = "actuator") -> None:
    """Follow the branch of ``result`` (a :class:`snapjump_cli.fe.solve.SceneResult` with its harmonic
    ``check``) and make its snap the design's answer in ``result.metrics`` (the keys of
    :data:`snapjump_cli.schema.FOLLOWED`; the replaced keys of a followed design describe the
    followed snap). A design that stays axisymmetric, or whose branch cannot be followed to a snap,
    keeps its axisymmetric answer (``followed`` False; ``follow_note`` says why)."""
    m = result.metrics
    t0 = time.perf_counter()
    try:
        answer = followed_metrics(result, check, N=N or None, mode=mode)
    except TimeLimitExceeded as exc:  # keep the axisymmetric answer, say why
        answer = FollowedAnswer(axisym_answer(m, f"branch not followed to its snap: {exc}"))
        answer.values["follow_n"] = check.asym_n
    result.follow = answer.branch
    m.update(answer.as_row())
    m["wall_s"] = (m.get("wall_s") or 0.0) + (time.perf_counter() - t0)
