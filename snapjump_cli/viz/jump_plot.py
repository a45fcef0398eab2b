"""The jump of one design: ``snapjump curve ... --jump FILE.png|.svg|.pdf``.

:func:`plot_jump` draws the mass-spring model's trajectory (docs/physics.md section 6;
:func:`snapjump_cli.jump.jump_trajectory`, the model ``snapjump rank`` applies): the heights of
both masses above the ground against time, ``y_i`` (the inner cap's lower pole, with the ring)
and ``y_o`` (the outer cap's pole, drawn at the spring's rest length above ``y_i`` plus its
extension), the ground impacts, the lift-offs (a resting ``m_i`` leaving the ground, or a rebound)
and the apex that gives ``y_jump``. Heights in mm, time in ms.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_jump", "lift_off_times"]


def lift_off_times(trajectory) -> list[float]:
    """Times [s] at which ``m_i`` leaves the ground: the start of every flight phase after a
    resting phase, and every impact followed by a flight (a rebound)."""
    out = []
    phases = trajectory.phases
    for (k0, _, t1), (k1, t0, _) in zip(phases[:-1], phases[1:]):
        if k0 == "rest" and k1 == "flight":
            out.append(float(t0))
    for t in trajectory.contact_times:
        later = [ph for ph in phases if ph[1] >= t - 1e-15]
        if later and later[0][0] == "flight":
            out.append(float(t))
    return sorted(set(out))


def plot_jump(trajectory, metrics: dict, path: str | Path, title: str = "", n: int = 1500) -> Path:
    """Draw the trajectory ``trajectory`` (:class:`snapjump_cli.jump.trajectory.JumpTrajectory`)
    and write it to ``path`` (format from the suffix: ``.png``, ``.svg``, ``.pdf``).

    Parameters
    ----------
    trajectory : the jump's trajectory
    metrics : the reported metrics (``y_jump_m``, ``h_imp_m``, ``dE_J``, ...; for the caption)
    path : the file
    title : the scene
    n : samples of the time axis

    Returns
    -------
    Path
        ``path``.
    """
    from snapjump_cli.viz.figures import _pyplot, _save

    plt = _pyplot()
    jr = trajectory.result
    t_peak = float(jr.t_peak_s)
    t_end = float(trajectory.t_end)
    t_show = min(t_end, max(2.0 * t_peak, 0.05 * t_end, 1e-3)) if t_peak > 0 else t_end
    t = np.unique(np.r_[np.linspace(0.0, t_show, n), [x for x in trajectory.contact_times if x <= t_show],
                        [t_peak] if t_peak <= t_show else []])
    yi, yo = trajectory.state(t)[:2]
    ms, mm = 1e3, 1e3
    fig, ax = plt.subplots(figsize=(6.4, 4.8), layout="constrained")
    try:
        ax.plot(t * ms, yo * mm, "-", color="tab:orange", lw=1.4, label=f"outer cap pole y_o (m_o = {jr.m_o * 1e3:.3g} g)")
        ax.plot(t * ms, yi * mm, "-", color="tab:blue", lw=1.6, label=f"inner cap pole y_i (m_i = {jr.m_i * 1e3:.3g} g)")
        ax.axhline(0.0, color="0.25", lw=1.0)
        ax.axhline(jr.h_imp_m * mm, color="0.5", lw=0.8, ls=":", label=f"start height h_imp = {jr.h_imp_m * mm:.3g} mm")
        lifts = [x for x in lift_off_times(trajectory) if x <= t_show]
        if lifts:
            ax.plot(np.array(lifts) * ms, trajectory.state(np.array(lifts))[0] * mm, "^", color="tab:green", ms=8,
                    mec="k", label="lift-off", zorder=5)
        imp = [x for x in trajectory.contact_times if x <= t_show]
        if imp:
            ax.plot(np.array(imp) * ms, np.zeros(len(imp)), "v", color="tab:red", ms=6, mec="k",
                    label="ground impact", zorder=5)
        if jr.jumped and t_peak <= t_show:
            ax.plot([t_peak * ms], [jr.y_jump_m * mm], "*", color="gold", ms=16, mec="k", zorder=6,
                    label=f"apex: y_jump = {jr.y_jump_m * mm:.4g} mm at {t_peak * ms:.3g} ms")
        else:
            ax.plot([], [], " ", label=f"no jump: {jr.reason or 'y_i never rises above h_imp'}")
        ax.set_xlabel("time after the snap [ms]")
        ax.set_ylabel("height above the ground [mm]")
        dE = metrics.get("dE_J")
        sub = f"dE = {dE * 1e3:.4g} mJ, " if dE else ""
        sub += f"k_s = {jr.k_s:.4g} N/m" + ("" if jr.complete else " (simulation stopped before the maximum was certain)")
        ax.set_title((f"{title}: " if title else "") + "the jump (mass-spring model)\n" + sub, fontsize=10)
        ax.grid(alpha=0.3)
        fig.legend(loc="outside lower center", ncols=2, fontsize=7.5, frameon=False)
        return _save(fig, path, 120)
    finally:
        plt.close(fig)
