"""The animation of what the actuator does: ``snapjump curve ... --animation FILE.gif``.

:func:`write_animation` shows the section (coloured by the largest principal stretch, standing on
the ground) moving along the path the actuator takes under volume control
(:func:`snapjump_cli.viz.actuator.actuator_path`): the stable states as the volume grows, then the
snap at fixed volume as a jump (a few frames blending the upper into the lower state, the point
on the curve dropping at constant volume), then the lower state; never the unstable branches the
continuation traced. A followed (or imperfect) state is drawn as two meridian sections (right
``phi = 0``, left ``phi = pi / n``), coloured by the stretch of its 3D deformation gradient.
Beside it, the state's point moves on the pressure-volume curve (kPa, ml), the traced
equilibrium path drawn thin underneath. The frames are the states, thinned evenly along the curve
to at most ``max_frames`` (the named states always kept, each held for a moment and named in the
frame). Written with matplotlib's ``PillowWriter`` (GIF), one figure draw per frame.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from snapjump_cli.viz.shapes import STATE_TITLES, STRETCH_LABEL, SectionDrawing, _pyplot, state_caption

__all__ = ["write_animation", "frame_steps", "animation_frames", "MAX_FRAMES", "JUMP_FRAMES"]

log = logging.getLogger(__name__)

#: Frames of an animation at most (a GIF of ~1-3 MB at the default size).
MAX_FRAMES = 90
_HOLD = 6  # frames a named state is held
#: Frames that blend the upper into the lower state at a jump (the snap at fixed volume).
JUMP_FRAMES = 6


def frame_steps(steps, max_frames: int = MAX_FRAMES) -> list[int]:
    """The steps to draw: evenly spaced along the p-V curve (normalised by its ranges), at most
    ``max_frames`` in all, every named state among them and each held for a few frames."""
    n = len(steps)
    named = [k for k in range(n) if steps.state[k]]
    x = (steps.V_m3 - steps.V_m3.min()) / max(np.ptp(steps.V_m3), 1e-300)
    y = (steps.p_Pa - steps.p_Pa.min()) / max(np.ptp(steps.p_Pa), 1e-300)
    d = np.r_[0.0, np.cumsum(np.hypot(np.diff(x), np.diff(y)))]
    budget = max(2, max_frames - (_HOLD - 1) * len(named))
    targets = np.linspace(0.0, d[-1], budget) if d[-1] > 0 else np.zeros(1)
    picked = sorted(set(np.searchsorted(d, targets).clip(0, n - 1).tolist()) | set(named))
    frames = []
    for k in picked:
        frames += [k] * (_HOLD if steps.state[k] else 1)
    return frames


def animation_frames(act, max_frames: int = MAX_FRAMES) -> list[tuple[int, float]]:
    """The frames of an :class:`~snapjump_cli.viz.actuator.ActuatorPath`: ``(k, t)`` pairs, the state
    ``k`` blended with the one before it by ``1 - t`` (``t = 1``: the state itself). States are
    chosen by :func:`frame_steps`; every state reached by a jump (``act.jump``) is preceded by the
    state it jumps from and :data:`JUMP_FRAMES` blends between the two. When the states are fewer
    than the frames allow (a path traced in long steps), blends of neighbouring states fill the
    loading evenly along the curve (a picture between two solved states, not a solved state)."""
    picked = frame_steps(act, max_frames)
    n_named = sum(1 for k in set(picked) if act.state[k])
    spare = max_frames - len(picked) - n_named * 0 - JUMP_FRAMES * int(np.sum(act.jump))
    x = (act.V_m3 - act.V_m3.min()) / max(np.ptp(act.V_m3), 1e-300)
    y = (act.p_Pa - act.p_Pa.min()) / max(np.ptp(act.p_Pa), 1e-300)
    seg = np.r_[0.0, np.hypot(np.diff(x), np.diff(y))]
    seg[np.asarray(act.jump, bool)] = 0.0
    total = float(seg.sum())
    out: list[tuple[int, float]] = []
    for i, k in enumerate(picked):
        first = i == 0 or picked[i - 1] != k
        if first and k > 0 and act.jump[k]:
            if not out or out[-1][0] != k - 1:
                out.append((k - 1, 1.0))
            if act.A[k].shape == act.A[k - 1].shape:
                out += [(k, t) for t in np.linspace(0.0, 1.0, JUMP_FRAMES + 2)[1:-1]]
        elif first and k > 0 and spare > 0 and total > 0 and out and out[-1][0] == k - 1 \
                and act.A[k].shape == act.A[k - 1].shape:
            m = int(round(spare * seg[k] / total))
            out += [(k, t) for t in np.linspace(0.0, 1.0, m + 2)[1:-1]]
        out.append((k, 1.0))
    return out


def write_animation(mesh, act, path: str | Path, *, title: str = "", volume_symbol: str = "V",
                    curve: dict | None = None, branch: dict | None = None,
                    max_frames: int = MAX_FRAMES, fps: int = 12, dpi: int = 80) -> Path:
    """Write the animation of the states ``act`` (:class:`~snapjump_cli.viz.actuator.ActuatorPath`)
    of ``mesh`` as a GIF.

    Parameters
    ----------
    mesh : the reference mesh (:class:`snapjump_cli.mesh.data.Mesh`)
    act : the states the actuator takes
    path : the ``.gif`` file (written atomically)
    title : the scene
    volume_symbol : ``V`` (a design's cavity volume) or ``ΔV`` (a single cap's supplied volume)
    curve : the traced axisymmetric path (``V_m3``, ``p_Pa``), drawn thin under the actuator's
    branch : a followed branch (:func:`snapjump_cli.fe.branch.metrics.branch_curve`), drawn thin too
    max_frames, fps, dpi : the frames at most (named states held), frames per second, resolution

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.animation import PillowWriter
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import Normalize

    from snapjump_cli.files import write_atomic
    from snapjump_cli.viz.actuator import opposite_phi, section_at

    plt = _pyplot()
    draw = SectionDrawing(mesh, subdivision=2)  # 4 sub-cells an element: the frames draw ~2x faster
    X = np.asarray(mesh.nodes, float)
    frames = animation_frames(act, max_frames)
    two = act.followed  # draw both sections of every frame

    def state(k: int, t: float):
        A = act.A[k] if t >= 1.0 else (1.0 - t) * act.A[k - 1] + t * act.A[k]
        hn = act.hn[k]
        if act.axisymmetric(k) and (t >= 1.0 or act.axisymmetric(k - 1)):
            x = section_at(X, hn, A, 0.0)
            return draw.halves(x), x
        phi_pi = opposite_phi(hn)
        x, x_pi = section_at(X, hn, A, 0.0), section_at(X, hn, A, phi_pi)
        return draw.halves(x, x_pi, (hn, A, phi_pi)), x

    parts, placed = {}, {}
    for f in dict.fromkeys(frames):
        parts[f], x = state(*f)
        placed[f] = draw.placed(x)[0]
    lam_all = np.concatenate([parts[f][1] for f in parts])
    top = max(float(np.percentile(lam_all, 99.5)), 1.0 + 1e-3)
    norm = Normalize(vmin=1.0, vmax=top)
    r, ylo, yhi, _ = draw.extent(list(placed.values()))
    fig, (ax, axc) = plt.subplots(1, 2, figsize=(9.0, 4.0), gridspec_kw={"width_ratios": [1.15, 1.0]},
                                  constrained_layout=True, dpi=dpi)
    try:
        f0 = frames[0]
        polys = PolyCollection(parts[f0][0], array=parts[f0][1], cmap="viridis", norm=norm, edgecolors="face",
                               linewidths=0.2)
        ax.add_collection(polys)
        lines = LineCollection(parts[f0][2], colors="k", linewidths=0.6)
        ax.add_collection(lines)
        draw.draw_ground(ax, r)
        ax.axvline(0.0, color="0.5", lw=0.6, ls=(0, (4, 3)))
        if two:
            phi_txt = opposite_phi(act.hn[-1])
            left = r"$\varphi = \pi$" if abs(phi_txt - np.pi) < 1e-12 else rf"$\varphi = \pi/{np.pi / phi_txt:.0f}$"
            for xpos, txt in ((-0.5 * r, left), (0.5 * r, r"$\varphi = 0$")):
                ax.text(xpos, yhi, txt, ha="center", va="top", fontsize=8)
        ax.set_xlim(-r, r)
        ax.set_ylim(ylo, yhi)
        ax.set_aspect("equal")
        ax.set_xlabel("r [mm]")
        ax.set_ylabel(f"height above {draw.ground_kind} [mm]")
        fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax,
                     label=STRETCH_LABEL + (" (3D)" if two else ""), shrink=0.85,
                     extend="max" if lam_all.max() > top * (1 + 1e-3) else "neither")
        V = act.V_m3 * 1e6
        p = act.p_Pa / 1e3
        if curve is not None and len(curve.get("V_m3", [])):
            axc.plot(np.asarray(curve["V_m3"]) * 1e6, np.asarray(curve["p_Pa"]) / 1e3, "-", color="0.7", lw=0.9,
                     label="traced equilibrium path" + (" (axisymmetric)" if two else ""))
        if branch is not None:
            axc.plot(np.asarray(branch["V_m3"]) * 1e6, np.asarray(branch["p_Pa"]) / 1e3, "-", color="#f5b971",
                     lw=0.9, label="followed branch, traced")
        seg = np.flatnonzero(act.jump)
        cuts = np.split(np.arange(len(act)), seg)
        for i, c in enumerate(cuts):
            axc.plot(V[c], p[c], "-", color="tab:blue", lw=1.6, label="what the actuator does" if i == 0 else None)
        for i, k in enumerate(seg):
            axc.plot([V[k - 1], V[k]], [p[k - 1], p[k]], "--", color="tab:red", lw=1.4,
                     label="snap (a jump at fixed volume)" if i == 0 else None)
        for name, face in (("upper", "k"), ("lower", "w"), ("bifurcation", "tab:orange")):
            k = act.index(name)
            if k is not None:
                axc.plot(V[k], p[k], "D" if name == "bifurcation" else "o", mfc=face, mec="k", ms=5)
        dot, = axc.plot([V[f0[0]]], [p[f0[0]]], "o", color="tab:red", ms=8, zorder=5)
        axc.legend(loc="lower right", fontsize=7)
        axc.set_xlabel(f"{volume_symbol} [ml]")
        axc.set_ylabel("p [kPa]")
        axc.grid(alpha=0.3)
        head = ax.set_title("", fontsize=10)
        if title:
            axc.set_title(title, fontsize=10)

        def update(f):
            k, t = f
            polys.set_verts(parts[f][0])
            polys.set_array(parts[f][1])
            lines.set_segments(parts[f][2])
            if t >= 1.0:
                vv, pp = act.V_m3[k], act.p_Pa[k]
                name = STATE_TITLES.get(act.state[k], "bifurcation" if act.state[k] == "bifurcation" else "")
                if not name:
                    name = act.branch[k] + " branch" if act.branch[k] != "axisymmetric" else "stable loading"
            elif act.jump[k]:
                vv, pp = act.V_m3[k], (1.0 - t) * act.p_Pa[k - 1] + t * act.p_Pa[k]
                name = "snapping (a jump at fixed volume)"
            else:  # a blend between two neighbouring states of the loading
                vv = (1.0 - t) * act.V_m3[k - 1] + t * act.V_m3[k]
                pp = (1.0 - t) * act.p_Pa[k - 1] + t * act.p_Pa[k]
                name = act.branch[k] + " branch" if act.branch[k] != "axisymmetric" else "stable loading"
            dot.set_data([vv * 1e6], [pp / 1e3])
            head.set_text(f"{name}\n{state_caption(pp, vv, volume_symbol)}")
            return polys, lines, dot, head

        update(f0)
        fig.canvas.draw()
        fig.set_layout_engine("none")  # laid out once: a layout per frame would double the time

        def write(tmp: Path) -> None:
            # the writer's own loop: one draw per frame (FuncAnimation.save draws each frame 3 times)
            writer = PillowWriter(fps=fps)
            with writer.saving(fig, str(tmp), dpi):
                for f in frames:
                    update(f)
                    writer.grab_frame()

        return write_atomic(path, write)
    finally:
        plt.close(fig)
