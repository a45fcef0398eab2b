"""The animation of a traced path: ``snapjump curve ... --animation FILE.gif``.

:func:`write_animation` shows the section (mirrored, coloured by the largest principal stretch,
standing on the ground) moving along the traced path, with the state's point moving on the
pressure-volume curve beside it. The frames are the path's steps, thinned evenly along the curve
to at most ``max_frames`` (the named states always kept, each held for a moment and named in the
frame). Written with matplotlib's ``PillowWriter`` (GIF), one figure draw per frame.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from snapjump_cli.viz.shapes import STATE_TITLES, STRETCH_LABEL, SectionDrawing, _pyplot, state_caption

__all__ = ["write_animation", "frame_steps", "MAX_FRAMES"]

log = logging.getLogger(__name__)

#: Frames of an animation at most (a GIF of ~1-3 MB at the default size).
MAX_FRAMES = 90
_HOLD = 6  # frames a named state is held


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


def write_animation(mesh, steps, path: str | Path, *, title: str = "", volume_symbol: str = "V",
                    max_frames: int = MAX_FRAMES, fps: int = 12, dpi: int = 80) -> Path:
    """Write the animation of ``steps`` (:class:`~snapjump_cli.viz.states.Steps`) of ``mesh`` as a GIF.

    Parameters
    ----------
    mesh : the reference mesh (:class:`snapjump_cli.mesh.data.Mesh`)
    steps : the scene's states in path order
    path : the ``.gif`` file (written atomically)
    title : the scene
    volume_symbol : ``V`` (a design's cavity volume) or ``ΔV`` (a single cap's supplied volume)
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

    plt = _pyplot()
    draw = SectionDrawing(mesh, subdivision=2)  # 4 sub-cells an element: the frames draw ~2x faster
    X = np.asarray(mesh.nodes, float)
    frames = frame_steps(steps, max_frames)
    shown = sorted(set(frames))
    placed = {k: draw.placed(X + steps.U[k])[0] for k in shown}
    parts = {k: draw.halves(X + steps.U[k]) for k in shown}
    lam_all = np.concatenate([parts[k][1] for k in shown])
    top = max(float(np.percentile(lam_all, 99.5)), 1.0 + 1e-3)
    norm = Normalize(vmin=1.0, vmax=top)
    r, ylo, yhi, _ = draw.extent(list(placed.values()))
    fig, (ax, axc) = plt.subplots(1, 2, figsize=(9.0, 4.0), gridspec_kw={"width_ratios": [1.15, 1.0]},
                                  constrained_layout=True, dpi=dpi)
    try:
        k0 = frames[0]
        polys = PolyCollection(parts[k0][0], array=parts[k0][1], cmap="viridis", norm=norm, edgecolors="face",
                               linewidths=0.2)
        ax.add_collection(polys)
        lines = LineCollection(parts[k0][2], colors="k", linewidths=0.6)
        ax.add_collection(lines)
        draw.draw_ground(ax, r)
        ax.axvline(0.0, color="0.5", lw=0.6, ls=(0, (4, 3)))
        ax.set_xlim(-r, r)
        ax.set_ylim(ylo, yhi)
        ax.set_aspect("equal")
        ax.set_xlabel("r [mm]")
        ax.set_ylabel(f"height above {draw.ground_kind} [mm]")
        fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax, label=STRETCH_LABEL, shrink=0.85,
                     extend="max" if lam_all.max() > top * (1 + 1e-3) else "neither")
        V = steps.V_m3 * 1e6
        p = steps.p_Pa / 1e3
        on = steps.on_path
        axc.plot(V[on], p[on], "-", color="tab:blue", lw=1.3)
        for name, face in (("upper", "k"), ("lower", "w")):
            k = steps.index(name)
            if k is not None:
                axc.plot(V[k], p[k], "o", mfc=face, mec="k", ms=5, label=STATE_TITLES[name].split(" (")[0])
        dot, = axc.plot([V[k0]], [p[k0]], "o", color="tab:red", ms=8, zorder=5, label="this frame")
        axc.legend(loc="lower right", fontsize=8)
        axc.set_xlabel(f"{volume_symbol} [ml]")
        axc.set_ylabel("p [kPa]")
        axc.grid(alpha=0.3)
        head = ax.set_title("", fontsize=10)
        if title:
            axc.set_title(title, fontsize=10)

        def update(k):
            polys.set_verts(parts[k][0])
            polys.set_array(parts[k][1])
            lines.set_segments(parts[k][2])
            dot.set_data([V[k]], [p[k]])
            name = STATE_TITLES.get(steps.state[k], f"step {k}")
            head.set_text(f"{name}\n{state_caption(steps.p_Pa[k], steps.V_m3[k], volume_symbol)}")
            return polys, lines, dot, head

        update(k0)
        fig.canvas.draw()
        fig.set_layout_engine("none")  # laid out once: a layout per frame would double the time

        def write(tmp: Path) -> None:
            # the writer's own loop: one draw per frame (FuncAnimation.save draws each frame 3 times)
            writer = PillowWriter(fps=fps)
            with writer.saving(fig, str(tmp), dpi):
                for k in frames:
                    update(k)
                    writer.grab_frame()

        return write_atomic(path, write)
    finally:
        plt.close(fig)
