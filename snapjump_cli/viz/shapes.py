"""Pictures of deformed sections: ``snapjump curve ... --shapes FILE.png``.

:func:`plot_shapes` draws states of a scene side by side, each as its meridian section mirrored
about the symmetry axis, coloured by the largest principal stretch, all at one scale, with the
ground line. :class:`SectionDrawing` does the drawing (the animation uses it too);
:func:`key_shape_states` picks the four states of a solved scene. matplotlib is imported inside
the functions that draw.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from snapjump_cli.viz.fields import element_points, principal_stretch, principal_stretch_3d

__all__ = ["ShapeState", "SectionDrawing", "plot_shapes", "key_shape_states", "followed_shape_states", "state_caption",
           "STRETCH_LABEL", "branch_shape_state", "actuator_shape_states"]

log = logging.getLogger(__name__)

STRETCH_LABEL = r"largest principal stretch $\lambda_{max}$"
_CMAP = "viridis"


@dataclass
class ShapeState:
    """One state to draw.

    Attributes
    ----------
    label : the panel's title (e.g. ``"upper state (V*)"``)
    p_Pa, V_m3 : the cavity pressure and the curve's volume, written under the label
    x : (n_nodes, 2) deformed ``(r, y)`` of every mesh node [m] in the meridian section
        ``phi = 0``, drawn as the right half
    x_pi : optional (n_nodes, 2) deformed ``(r, y)`` in the section ``phi = pi`` [m], ``r`` measured
        from the axis outwards in that half-plane (a node at ``r`` is drawn at ``-r``). An
        axisymmetric state leaves it ``None`` and its left half is the mirror image of ``x``; a
        non-axisymmetric state gives both (e.g. ``X + U0 + U1`` and ``X + U0 - U1`` for the
        harmonic ``n = 1``, in that half-plane's own radial direction), and each half is drawn from
        its own section.
    note : an optional line under the caption
    hn, A : for a non-axisymmetric state, its harmonics and nodal amplitudes [m] (the layout of
        :mod:`snapjump_kernels.multiharmonic`): the stretch of each half is then the largest
        principal stretch of the full 3D deformation gradient in its section
        (:func:`snapjump_cli.viz.fields.principal_stretch_3d`); without them, that of the
        axisymmetric map of ``x``
    phi_pi : the angle of the section drawn as the left half (``pi``; ``pi / n`` for a state of
        harmonics ``n, 2n, ...``)
    """

    label: str
    p_Pa: float
    V_m3: float
    x: np.ndarray
    x_pi: np.ndarray | None = None
    note: str = ""
    hn: np.ndarray | None = None
    A: np.ndarray | None = None
    phi_pi: float = float(np.pi)

    @property
    def stretch3d(self) -> tuple | None:
        """``(hn, A, phi_pi)`` when the stretch comes from the 3D deformation gradient."""
        return None if self.A is None else (self.hn, self.A, self.phi_pi)


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def state_caption(p_Pa: float, V_m3: float, volume_symbol: str = "V") -> str:
    """``p = 7.68 kPa, V = 122.1 ml`` (``volume_symbol`` ``ΔV`` for the supplied volume of a cap)."""
    ml = V_m3 * 1e6
    ml = 0.0 if abs(ml) < 1e-9 else ml  # the round-off of a volume that is zero
    return f"p = {p_Pa / 1e3:.3g} kPa, {volume_symbol} = {ml:.4g} ml"


class SectionDrawing:
    """A mesh's section as polygons for matplotlib, mirrored about the axis.

    Every element is split into ``m x m`` sub-cells (by default ``m`` = 3 for Q9, 2 for Q4), each coloured by
    the largest principal stretch at its centre; region boundaries (inner cap, ring, outer cap)
    are drawn as lines along the curved element edges. Coordinates are drawn in millimetres,
    heights above ``y_ground``.

    Parameters
    ----------
    mesh : the reference mesh (:class:`snapjump_cli.mesh.data.Mesh`, metres)
    subdivision : sub-cells per element side (default: 3 for Q9, 2 for Q4)
    """

    def __init__(self, mesh, subdivision: int | None = None) -> None:
        self.mesh = mesh
        self.X = np.asarray(mesh.nodes, float)
        self.elements = np.asarray(mesh.elements)
        self.order = int(mesh.order)
        m = subdivision or (3 if self.order == 2 else 2)
        g = np.linspace(-1.0, 1.0, m + 1)
        c = 0.5 * (g[:-1] + g[1:])
        corners = []
        for j in range(m):
            for i in range(m):
                corners += [(g[i], g[j]), (g[i + 1], g[j]), (g[i + 1], g[j + 1]), (g[i], g[j + 1])]
        self._xi_cells = np.array(corners)  # (m*m*4, 2)
        self._xi_centres = np.array([(c[i], c[j]) for j in range(m) for i in range(m)])
        self._ncell = m * m
        t = np.linspace(-1.0, 1.0, 7)
        one = np.ones_like(t)
        self._xi_sides = [np.column_stack(s) for s in ((t, -one), (one, t), (t[::-1], one), (-one, t[::-1]))]
        self._boundary = self._region_boundaries()
        ground = mesh.node_sets.get("ground")
        if ground is None or len(ground) == 0:
            ground = mesh.node_sets.get("base", np.zeros(0, int))
        self.ground_kind = "ground" if len(mesh.node_sets.get("ground", [])) else "base"
        self.y_ground = float(self.X[np.asarray(ground, int), 1].min()) if len(ground) else float(self.X[:, 1].min())

    def _region_boundaries(self) -> list[tuple[int, int]]:
        """``(element, side)`` pairs on the boundary of their region (or of the mesh)."""
        corner = self.elements[:, :4]
        sides = [(0, 1), (1, 2), (2, 3), (3, 0)]
        count: dict[tuple[int, int, int], int] = {}
        for e in range(len(corner)):
            reg = int(self.mesh.region[e])
            for a, b in sides:
                key = (reg, *sorted((int(corner[e, a]), int(corner[e, b]))))
                count[key] = count.get(key, 0) + 1
        out = []
        for e in range(len(corner)):
            reg = int(self.mesh.region[e])
            for s, (a, b) in enumerate(sides):
                if count[(reg, *sorted((int(corner[e, a]), int(corner[e, b]))))] == 1:
                    out.append((e, s))
        return out

    def cells(self, x: np.ndarray, mirror: bool = False, stretch3d: tuple | None = None,
              phi: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Sub-cell polygons ``(n_cells, 4, 2)`` [mm] of the section at node positions ``x`` [m]
        (``mirror``: drawn at ``-r``) and the stretch at their centres ``(n_cells,)``: that of the
        axisymmetric map of ``x``, or with ``stretch3d = (hn, A, ...)`` that of the 3D deformation
        gradient of the Fourier amplitudes ``A`` in the section at ``phi``."""
        P = element_points(x, self.elements, self.order, self._xi_cells).reshape(-1, 4, 2)
        if stretch3d is None:
            lam = principal_stretch(self.X, x, self.elements, self.order, self._xi_centres).ravel()
        else:
            lam = principal_stretch_3d(self.X, stretch3d[1], stretch3d[0], self.elements, self.order,
                                       self._xi_centres, phi).ravel()
        return self._to_mm(P, mirror), lam

    def outline(self, x: np.ndarray, mirror: bool = False) -> list[np.ndarray]:
        """Region boundary polylines [mm] at node positions ``x`` [m]."""
        out = []
        for s in range(4):
            es = [e for e, side in self._boundary if side == s]
            if es:
                P = element_points(x, self.elements[es], self.order, self._xi_sides[s])
                out += list(self._to_mm(P, mirror))
        return out

    def _to_mm(self, P: np.ndarray, mirror: bool) -> np.ndarray:
        Q = np.empty_like(P)
        Q[..., 0] = (-P[..., 0] if mirror else P[..., 0]) * 1e3
        Q[..., 1] = (P[..., 1] - self.y_ground) * 1e3
        return Q

    def placed(self, x: np.ndarray, x_pi: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """A state as it stands on the ground: shifted up or down so that its lowest ring-bottom
        node touches the ground line (the jump model's resting state; the solver holds only point
        6 vertically). Scenes without a ring (a cap on its base) are drawn as they are."""
        ground = self.mesh.node_sets.get("ground")
        if ground is None or len(ground) == 0:
            return x, x_pi
        g = np.asarray(ground, int)
        low = min(float(x[g, 1].min()), float(x_pi[g, 1].min()) if x_pi is not None else np.inf)
        shift = np.array([0.0, self.y_ground - low])
        return x + shift, (x_pi + shift if x_pi is not None else None)

    def halves(self, x: np.ndarray, x_pi: np.ndarray | None = None,
               stretch3d: tuple | None = None) -> tuple[np.ndarray, np.ndarray, list]:
        """Both halves of a state: polygons, stretch and outlines (left half from ``x_pi`` if given),
        as it stands on the ground (:meth:`placed`). ``stretch3d = (hn, A, phi_pi)``: the stretch of
        the 3D deformation gradient of the amplitudes ``A`` (right half ``phi = 0``, left half
        ``phi_pi``)."""
        x, x_pi = self.placed(x, x_pi)
        right, lam_r = self.cells(x, stretch3d=stretch3d, phi=0.0)
        left, lam_l = self.cells(x if x_pi is None else x_pi, mirror=True, stretch3d=stretch3d,
                                 phi=stretch3d[2] if stretch3d is not None else 0.0)
        lines = self.outline(x) + self.outline(x if x_pi is None else x_pi, mirror=True)
        return np.concatenate([left, right]), np.concatenate([lam_l, lam_r]), lines

    def extent(self, xs: Sequence[np.ndarray]) -> tuple[float, float, float, float]:
        """``(r_max, y_min, y_max)`` [mm] over node positions ``xs`` (with the ground line), plus a margin."""
        r = max(float(np.abs(x[:, 0]).max()) for x in xs) * 1e3
        ylo = min(float(x[:, 1].min()) for x in xs)
        yhi = max(float(x[:, 1].max()) for x in xs)
        ylo = (min(ylo, self.y_ground) - self.y_ground) * 1e3
        yhi = (yhi - self.y_ground) * 1e3
        pad = 0.06 * max(r, yhi - ylo)
        return r + pad, ylo - pad, yhi + pad, pad

    def name_parts(self, ax: Any, r: float, ylo: float, yhi: float) -> None:
        """Name the parts of the undeformed section on its left half (a design: inner cap, ring,
        outer cap): the outer cap from above, the others from below the ground line."""
        from snapjump_cli.mesh.data import REGION_NAMES

        if ylo > -0.15 * r or len(set(self.mesh.region.tolist())) < 2:
            return
        X = self.X
        spots = {"inner_cap": (0.4, "lower", (-0.15, 0.55)), "ring": (None, "", (-0.85, 0.55)),
                 "outer_cap": (0.6, "upper", (-0.7, None))}
        for reg, name in sorted(REGION_NAMES.items()):
            sel = self.mesh.region == reg
            if not sel.any() or name not in spots:
                continue
            frac, side, (xt, yt) = spots[name]
            nodes = np.unique(self.elements[sel])
            if frac is None:
                tip = X[nodes].mean(axis=0)
            else:  # a node at ``frac`` of the region's radial extent, on its upper or lower surface
                rr = X[nodes, 0]
                near = nodes[np.argsort(np.abs(rr - frac * rr.max()))[:12]]
                tip = X[near[np.argmax(X[near, 1]) if side == "upper" else np.argmin(X[near, 1])]]
            tip_mm = (-tip[0] * 1e3, (tip[1] - self.y_ground) * 1e3)
            text_y = yt * ylo if yt is not None else 0.5 * (yhi + tip_mm[1])
            ax.annotate(name.replace("_", " "), tip_mm, xytext=(xt * r, text_y), fontsize=7.5, ha="center",
                        va="center", arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "0.2"})

    def draw_ground(self, ax: Any, r: float) -> None:
        """The ground line (the ring's bottom face, undeformed; or a single cap's base plane)."""
        ax.axhline(0.0, color="0.25", lw=1.0, zorder=1)
        ax.fill_between([-r, r], [0, 0], [-0.04 * r, -0.04 * r], color="0.85", zorder=0, lw=0)


def plot_shapes(mesh, states: Sequence[ShapeState], path: str | Path, *, title: str = "",
                volume_symbol: str = "V", dpi: int = 150) -> Path:
    """Draw ``states`` of one mesh side by side (a 2 x 2 grid for four) and write a PNG.

    Parameters
    ----------
    mesh : the reference mesh the states displace (:class:`snapjump_cli.mesh.data.Mesh`)
    states : the states (:class:`ShapeState`); each is drawn mirrored about the axis, or, with
        ``x_pi``, as its two meridian sections (left ``phi = pi``, right ``phi = 0``)
    path : the PNG file, written atomically
    title : the figure's title (the scene)
    volume_symbol : ``V`` (a design's cavity volume) or ``ΔV`` (a single cap's supplied volume)
    dpi : resolution

    Returns
    -------
    Path
        ``path``.
    """
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import Normalize

    from snapjump_cli.files import write_atomic

    plt = _pyplot()
    draw = SectionDrawing(mesh)
    parts = [draw.halves(s.x, s.x_pi, s.stretch3d) for s in states]
    lam_all = np.concatenate([lam for _, lam, _ in parts])
    lam_max = float(lam_all.max())
    # the colour scale ends at the 99.5th percentile of the sub-cells: a corner's peak (where the
    # outer cap meets the ring) would otherwise leave the rest of the section in one colour
    top = max(float(np.percentile(lam_all, 99.5)), 1.0 + 1e-3)
    norm = Normalize(vmin=1.0, vmax=top)
    extend = "max" if lam_max > top * (1 + 1e-3) else "neither"
    placed = [draw.placed(s.x, s.x_pi) for s in states]
    r, ylo, yhi, pad = draw.extent([x for x, _ in placed] + [x for _, x in placed if x is not None])
    n = len(states)
    ncols = 2 if n == 4 else min(n, 3)
    nrows = -(-n // ncols)
    panel_w = 3.2  # inches of drawing per panel; the height follows the data's aspect
    panel_h = panel_w * (yhi - ylo) / (2 * r) + 0.62
    fig, axes = plt.subplots(nrows, ncols, figsize=(panel_w * ncols + 1.5, panel_h * nrows + 0.75),
                             sharex=True, sharey=True, squeeze=False, constrained_layout=True)
    try:
        for ax in axes.ravel()[n:]:
            ax.set_visible(False)
        for ax, s, (polys, lam, lines) in zip(axes.ravel(), states, parts):
            ax.add_collection(PolyCollection(polys, array=lam, cmap=_CMAP, norm=norm, edgecolors="face",
                                             linewidths=0.2))
            ax.add_collection(LineCollection(lines, colors="k", linewidths=0.6))
            draw.draw_ground(ax, r)
            ax.axvline(0.0, color="0.5", lw=0.6, ls=(0, (4, 3)), zorder=3)
            caption = state_caption(s.p_Pa, s.V_m3, volume_symbol)
            note = s.note
            if draw.ground_kind == "ground" and polys[..., 1].min() < -0.02 * r:
                note = (note + "\n" if note else "") + "(below ground: no contact in the model)"
            ax.set_title(f"{s.label}\n{caption}" + (f"\n{note}" if note else ""), fontsize=9)
            if s.x_pi is not None:
                left = r"$\varphi = \pi$" if abs(s.phi_pi - np.pi) < 1e-12 else rf"$\varphi = \pi/{np.pi / s.phi_pi:.0f}$"
                for xpos, txt in ((-0.5 * r, left), (0.5 * r, r"$\varphi = 0$")):
                    ax.text(xpos, ylo + 0.5 * pad, txt, ha="center", va="bottom", fontsize=8)
            ax.set_xlim(-r, r)
            ax.set_ylim(ylo, yhi)
            ax.set_aspect("equal")
            ax.tick_params(labelsize=8)
        for ax in axes[-1, :]:
            ax.set_xlabel("r [mm]", fontsize=9)
        for ax in axes[:, 0]:
            ax.set_ylabel(f"height above {draw.ground_kind} [mm]", fontsize=9)
        sm = plt.cm.ScalarMappable(norm=norm, cmap=_CMAP)
        label = STRETCH_LABEL + (f" (largest {lam_max:.3g})" if extend == "max" else "")
        fig.colorbar(sm, ax=axes.ravel().tolist(), label=label, shrink=0.8, extend=extend)
        if states and states[0].label == STATE_TITLES["start"]:
            draw.name_parts(axes.ravel()[0], r, ylo, yhi)
        if title:
            fig.suptitle(title, fontsize=10)
        fmt = Path(path).suffix.lstrip(".").lower() or "png"
        return write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))
    finally:
        plt.close(fig)


#: Panel titles of the named states.
STATE_TITLES = {
    "start": "undeformed",
    "p_max": "pressure maximum",
    "upper": "upper state (volume limit V*)",
    "lower": "lower state (after the snap, at V*)",
}


def key_shape_states(steps, X: np.ndarray) -> list[ShapeState]:
    """The four states of a solved scene from its :class:`~snapjump_cli.viz.states.Steps`: undeformed,
    pressure maximum, upper and lower state. Without a snap: undeformed, pressure maximum and the
    last traced state. A lower state found off the path is noted as such."""
    out = []
    names = ["start", "p_max", "upper", "lower"]
    for name in names:
        k = steps.index(name)
        note = ""
        if k is None and name == "p_max" and steps.index("upper") is not None:
            k, note = steps.index("upper"), "(= the upper state: p still rises at V*)"
        if k is None:
            continue
        if name == "lower" and not steps.on_path[k]:
            note = "(at fixed volume, off the path)"
        out.append(ShapeState(STATE_TITLES[name], float(steps.p_Pa[k]), float(steps.V_m3[k]), X + steps.U[k],
                              note=note))
    if steps.index("upper") is None:
        k = len(steps) - 1
        if steps.index("p_max") == k:  # the pressure rises to the end of the trace: one panel for both
            out[-1].note = "(the last traced state: no snap)"
        else:
            out.append(ShapeState("last traced state (no snap)", float(steps.p_Pa[k]), float(steps.V_m3[k]),
                                  X + steps.U[k]))
    return out


def followed_shape_states(fr) -> list[ShapeState]:
    """The followed snap's upper and lower states (``fr``: :class:`snapjump_cli.fe.branch.trace.FollowResult`)
    (SI), each with its two meridian sections ``phi = 0`` (right half) and ``phi = pi / n`` (left
    half), coloured by the largest principal stretch of the 3D deformation gradient."""
    mh, st, sc = fr.model, fr.states, fr.tracer.sc
    if st.upper is None or st.lower is None:
        return []
    sec = getattr(fr, "secondary", None)
    which = f"n = {fr.bif.n}" + (f", then n = {sec.n}" if sec is not None else "")  # (a secondary branch's)
    return [branch_shape_state(mh, pt, sc, f"{name} ({which})")
            for name, pt in (("followed upper state (V*)", st.upper), ("followed lower state (after the snap)", st.lower))]


def branch_shape_state(mh, pt, sc, label: str, note: str = "") -> ShapeState:
    """A state of a multi-harmonic model (:class:`snapjump_cli.fe.branch.model.MultiHarmonicModel`)
    as a :class:`ShapeState` with its two sections and its 3D stretch."""
    from snapjump_cli.viz.actuator import opposite_phi, section_at

    L, S = mh.L, mh.S
    A = mh.total_amplitudes(pt.u) * L
    X = np.asarray(mh.mesh.nodes, float)
    phi_pi = opposite_phi(mh.hn)
    return ShapeState(label, float(pt.p * S), float(pt.zeta[0] * sc[0] * L**3), section_at(X, mh.hn, A, 0.0),
                      section_at(X, mh.hn, A, phi_pi), note=note, hn=np.asarray(mh.hn), A=A, phi_pi=phi_pi)


def actuator_shape_states(act) -> list[ShapeState]:
    """The panels of a followed (or imperfect) solve from its :class:`~snapjump_cli.viz.actuator.ActuatorPath`:
    undeformed, the pressure maximum (when the actuator passes it), the bifurcation, the upper
    state and the lower state, each from the states the actuator takes."""
    titles = {"start": STATE_TITLES["start"], "p_max": STATE_TITLES["p_max"],
              "bifurcation": "bifurcation (leaves the axisymmetric path)",
              "upper": "upper state (volume limit V*)", "lower": "lower state (after the snap, at V*)"}
    out = []
    for name in ("start", "p_max", "bifurcation", "upper", "lower"):
        k = act.index(name)
        if k is None:
            continue
        label = titles[name] + (f" [{act.branch[k]}]" if act.branch[k] != "axisymmetric" and name != "bifurcation" else "")
        if act.axisymmetric(k):
            out.append(ShapeState(label, float(act.p_Pa[k]), float(act.V_m3[k]), act.section(k)))
        else:
            from snapjump_cli.viz.actuator import opposite_phi

            phi_pi = opposite_phi(act.hn[k])
            out.append(ShapeState(label, float(act.p_Pa[k]), float(act.V_m3[k]), act.section(k, 0.0),
                                  act.section(k, phi_pi), hn=act.hn[k], A=act.A[k], phi_pi=phi_pi))
    return out
