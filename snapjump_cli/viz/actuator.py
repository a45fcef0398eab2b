"""The path the actuator takes under volume control: what ``--animation`` plays and what
``--export`` writes for a followed (or imperfect) solve.

A traced equilibrium path goes through its volume limit and back along unstable states; an
actuator inflated by a syringe (water: volume control) does not. It passes through the stable
states as the volume grows, and at the volume limit ``V*`` it *snaps*: it jumps at that fixed
volume to the lower state, and inflation goes on from there. :func:`actuator_path` turns a solved
scene into that sequence of states (:class:`ActuatorPath`):

* the loading path, from rest, as far as the volume grows (every step whose volume exceeds all
  before it; the pressure maximum kept);
* for a followed solve (``--harmonics N --follow``), only up to the bifurcation: from there the
  followed branch (the sections of its Fourier series), through any fold it jumps past
  (:attr:`ActuatorPath.jump`), to its own volume limit; for a branch that left another at a
  secondary bifurcation, that one first;
* the snap: the upper state, then the lower state at the same volume (``jump`` true);
* after the lower state, the traced path's states beyond ``V*`` (a ``--full`` trace) as the
  volume grows again.

Every state is kept as the nodal amplitudes of a Fourier series in the circumferential angle
(harmonic 0 alone for an axisymmetric state; :mod:`snapjump_kernels.multiharmonic`'s layout) in
metres, from which :meth:`ActuatorPath.section` gives any meridian section and
:func:`snapjump_cli.viz.fields.principal_stretch_3d` the stretch of the 3D deformation gradient.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ActuatorPath", "actuator_path", "branch_of", "branch_rows", "section_at", "opposite_phi"]

log = logging.getLogger(__name__)

_AXI_HN = np.zeros(1, np.int64)


def section_at(X: np.ndarray, hn, A: np.ndarray, phi: float) -> np.ndarray:
    """The deformed ``(r, z)`` of every node (n, 2) in the meridian section at ``phi`` (``r`` the
    radial coordinate of each material ring; the circumferential displacement moves points out of
    the section and is not shown)."""
    x = np.array(X, float, copy=True)
    for k, n in enumerate(hn):
        o = 0 if k == 0 else 2 + 3 * (k - 1)
        x[:, 0] += A[:, o] * np.cos(n * phi)
        x[:, 1] += A[:, o + 1] * np.cos(n * phi)
    return x


def opposite_phi(hn) -> float:
    """The meridian section drawn as the left half beside ``phi = 0``: ``pi / n_1`` (``n_1`` the
    lowest harmonic kept), where the lowest harmonic is most unlike ``phi = 0``; ``pi`` for an
    axisymmetric state."""
    hn = np.asarray(hn)
    return float(np.pi / hn[1]) if len(hn) > 1 else float(np.pi)


@dataclass
class ActuatorPath:
    """States in the order the actuator takes them (SI units; ``n`` states).

    Attributes
    ----------
    hn : per state, the harmonics of its amplitudes (``[0]`` for an axisymmetric state)
    A : per state, the nodal amplitudes ``(n_nodes, 2 + 3 (K - 1))`` from the perfect reference [m]
    p_Pa, V_m3 : (n,) the cavity pressure and the curve's volume
    state : (n,) ``""`` or ``start``, ``p_max``, ``bifurcation``, ``upper``, ``lower``
    jump : (n,) the state is reached by a jump at fixed volume from the one before
    branch : (n,) ``axisymmetric``, ``followed`` or ``imperfect``
    X : (n_nodes, 2) the reference nodes [m]
    """

    hn: list
    A: list
    p_Pa: np.ndarray
    V_m3: np.ndarray
    state: list[str]
    jump: np.ndarray
    branch: list[str]
    X: np.ndarray = field(repr=False, default=None)

    def __len__(self) -> int:
        return len(self.state)

    def index(self, name: str) -> int | None:
        """The state named ``name`` (the last one: a followed solve's ``upper`` is its own)."""
        idx = [k for k, s in enumerate(self.state) if s == name]
        return idx[-1] if idx else None

    def axisymmetric(self, k: int) -> bool:
        """Whether state ``k`` is axisymmetric (no harmonic beyond 0, or all of them zero)."""
        return len(self.hn[k]) == 1 or not np.any(self.A[k][:, 2:])

    def section(self, k: int, phi: float = 0.0) -> np.ndarray:
        """Deformed ``(r, z)`` [m] of every node in the meridian section at ``phi``."""
        return section_at(self.X, self.hn[k], self.A[k], phi)

    def displacement_2d(self, k: int) -> np.ndarray:
        """The displacement ``(u_r, u_z)`` [m] of the section ``phi = 0``."""
        return self.section(k, 0.0) - self.X

    @property
    def followed(self) -> bool:
        """Whether any state is not axisymmetric (a followed or imperfect solve)."""
        return any(not self.axisymmetric(k) for k in range(len(self)))


def branch_of(res):
    """The non-axisymmetric branch the answer of ``res`` comes from and its kind: ``(fr,
    "followed")`` for a followed solve whose followed snap is the answer, ``(None, "")`` otherwise."""
    fr = getattr(res, "follow", None)
    if fr is not None and res.metrics.get("followed") and fr.states.upper is not None:
        return fr, "followed"
    return None, ""


def _axi_amplitudes(U: np.ndarray) -> np.ndarray:
    return np.asarray(U, float).copy()


def _mh_amplitudes(mh, u: np.ndarray) -> np.ndarray:
    return mh.total_amplitudes(u) * mh.L


def _monotone(points, V, start_max: float = -np.inf) -> list[int]:
    """Indices of the points whose volume exceeds all before them (and ``start_max``)."""
    keep, vmax = [], start_max
    for i, v in enumerate(V):
        if v > vmax:
            keep.append(i)
            vmax = v
    return keep


def _branch_points(fr) -> list[tuple[object, np.ndarray, object]]:
    """``(model, volume scale, point)`` of a followed branch in path order from the bifurcation (a
    branch that left another one: that one up to the secondary bifurcation, or up to the fold
    it jumps from, first)."""
    out = []
    sec = getattr(fr, "secondary", None)
    jump = fr.kind == "jump"
    if fr.parent is not None and sec is not None:
        head = fr.parent.path.points[: sec.index + 1] + ([] if jump else [sec.point])
        out += [(fr.parent.model, fr.parent.tracer.sc, pt) for pt in head]
    out += [(fr.model, fr.tracer.sc, pt) for pt in fr.path.points]
    return out


def actuator_path(res, steps, branch=None, kind: str = "followed") -> ActuatorPath:
    """The states the actuator takes (module docstring).

    Parameters
    ----------
    res : the solved scene (:class:`snapjump_cli.fe.solve.SceneResult`)
    steps : its traced path as :class:`snapjump_cli.viz.states.Steps`
    branch : the branch whose snap is the answer (a :class:`snapjump_cli.fe.branch.trace.FollowResult`
        or an imperfect actuator's :class:`snapjump_cli.fe.branch.imperfection.ImperfectResult`), or
        ``None`` (the axisymmetric path's snap); default :func:`branch_of`
    kind : the branch's name (``followed`` or ``imperfect``)

    Returns
    -------
    ActuatorPath
    """
    if branch is None:
        branch, k0 = branch_of(res)
        kind = k0 or kind
    X = np.asarray(res.model.mesh.nodes, float)
    hn, A, p, V, state, jump, br = [], [], [], [], [], [], []

    def add(h, a, pp, vv, name, j, b):
        hn.append(np.asarray(h))
        A.append(a)
        p.append(float(pp))
        V.append(float(vv))
        state.append(name)
        jump.append(bool(j))
        br.append(b)

    ku, kl = steps.index("upper"), steps.index("lower")
    if branch is None:
        last = ku if ku is not None else len(steps) - 1
        vmax = -np.inf
        for k in range(last + 1):
            if steps.V_m3[k] > vmax or steps.state[k]:
                add(_AXI_HN, _axi_amplitudes(steps.U[k]), steps.p_Pa[k], steps.V_m3[k], steps.state[k], False,
                    "axisymmetric")
                vmax = max(vmax, steps.V_m3[k])
        if ku is not None and kl is not None:
            add(_AXI_HN, _axi_amplitudes(steps.U[kl]), steps.p_Pa[kl], steps.V_m3[kl], "lower", True, "axisymmetric")
            vmax = steps.V_m3[kl]
            for k in range(kl + 1, len(steps)):
                if steps.on_path[k] and steps.V_m3[k] > vmax:
                    add(_AXI_HN, _axi_amplitudes(steps.U[k]), steps.p_Pa[k], steps.V_m3[k], steps.state[k], False,
                        "axisymmetric")
                    vmax = steps.V_m3[k]
        return ActuatorPath(hn, A, np.array(p), np.array(V), state, np.array(jump), br, X)

    mh, st, sc = branch.model, branch.states, branch.tracer.sc
    L, S = mh.L, mh.S
    if kind == "followed":
        bif = branch.bif
        V_bif = float(bif.zeta[0] * sc[0] * L**3)
        vmax = -np.inf
        for k in range(len(steps)):  # the axisymmetric loading path up to the bifurcation
            if ku is not None and k > ku:
                break
            if steps.V_m3[k] < V_bif and (steps.V_m3[k] > vmax or steps.state[k]):
                add(_AXI_HN, _axi_amplitudes(steps.U[k]), steps.p_Pa[k], steps.V_m3[k],
                    steps.state[k] if steps.state[k] in ("start", "p_max") else "", False, "axisymmetric")
                vmax = max(vmax, steps.V_m3[k])
        add(mh.hn, _mh_amplitudes(mh, mh.embed(bif.u)), bif.p * S, V_bif, "bifurcation", False, kind)
        pts = _branch_points(branch)[1:]  # the first point is the bifurcation itself
        start_max = V_bif
    else:  # an imperfect actuator: its own path from rest
        pts = [(mh, sc, pt) for pt in branch.path.points]
        start_max = -np.inf
    up = st.upper
    V_up = float(up.zeta[0] * sc[0] * L**3) if up is not None else np.inf
    vmax, prev_kept = start_max, True
    for model, sc_k, pt in pts:
        v = float(pt.zeta[0] * sc_k[0] * L**3)
        if pt is up or v >= V_up:
            break
        if v > vmax:
            add(model.hn, _mh_amplitudes(model, pt.u), pt.p * S, v, "start" if not state else "", not prev_kept,
                kind)
            vmax, prev_kept = v, True
        else:
            prev_kept = False
    if up is not None:
        add(mh.hn, _mh_amplitudes(mh, up.u), up.p * S, V_up, "upper", False, kind)
        if st.lower is not None:
            lo = st.lower
            add(mh.hn, _mh_amplitudes(mh, lo.u), lo.p * S, float(lo.zeta[0] * sc[0] * L**3), "lower", True, kind)
    return ActuatorPath(hn, A, np.array(p), np.array(V), state, np.array(jump), br, X)


def branch_rows(res, branch, kind: str = "followed") -> dict[str, list]:
    """The traced points of a followed (or imperfect) branch as ``--csv`` rows (the columns of
    :meth:`snapjump_cli.viz.states.Steps.columns` plus ``branch``): ``p_Pa``, ``V_m3``,
    ``y_pole_m`` (the pole's height, the axisymmetric part), ``strain_energy_J``, ``arc_length``
    (the branch's own), ``state`` (``bifurcation``, ``upper``, ``lower`` or empty), ``on_path``."""
    mh, st, sc = branch.model, branch.states, branch.tracer.sc
    L, S = mh.L, mh.S
    pole = int(mh.mesh.node_sets["pole_lower"][0])
    seq: list[tuple[object, np.ndarray, object, str, bool]] = [(m, s, pt, "", True) for m, s, pt in (
        _branch_points(branch) if kind == "followed" else [(mh, sc, pt) for pt in branch.path.points])]
    if kind == "followed" and seq:
        seq[0] = (*seq[0][:3], "bifurcation", True)
    up, lo = st.upper, st.lower
    if up is not None:  # the upper and lower states at their arc length (or the lower state last, off the path)
        ins = [(up, "upper")] + ([(lo, "lower")] if lo is not None else [])
        for state, name in ins:
            on = name == "upper" or st.lower_method == "path"
            if on:
                pos = next((i for i, (m, _, pt, _, _) in enumerate(seq) if m is mh and pt.s > state.s), len(seq))
                seq.insert(pos, (mh, sc, state, name, True))
            else:
                seq.append((mh, sc, state, name, False))
    cols: dict[str, list] = {"p_Pa": [], "V_m3": [], "y_pole_m": [], "strain_energy_J": [], "arc_length": [],
                             "state": [], "on_path": []}
    for m, s, pt, name, on in seq:
        cols["p_Pa"].append(float(pt.p * S))
        cols["V_m3"].append(float(pt.zeta[0] * s[0] * L**3))
        A0 = m.total_amplitudes(pt.u)
        cols["y_pole_m"].append(float((m.X[pole, 1] + A0[pole, 1]) * L))
        cols["strain_energy_J"].append(float(m.energy(pt.u) * S * L**3))
        cols["arc_length"].append(float(pt.s) if on else float("nan"))
        cols["state"].append(name)
        cols["on_path"].append(int(on))
    return cols
