"""The states of a solved scene as steps: what the ``curve`` command's ``--csv``, ``--shapes``,
``--animation`` and ``--export`` show.

:func:`path_steps` turns a :class:`~snapjump_cli.fe.solve.SceneResult` into one sequence of states
(:class:`Steps`, SI units): the traced path's points with the named states inserted at their arc
length,

* ``start``: the stress-free state (step 0);
* ``p_max``: the pressure maximum of the loading path (the state where ``dp/ds = 0`` on the step
  that holds the maximum of ``metrics["p_max_Pa"]``, solved on the path; the upper state itself
  when the pressure still rises at ``V*``);
* ``upper``: the upper state at the volume limit ``V*``;
* ``lower``: the lower state at ``V*``. On the path when ``lower_state_method`` is ``path``; a
  lower state found at fixed volume off the path (``descent``) is the last step, with
  ``on_path`` false and no arc length.

Every step carries its displacement (metres), cavity pressure and volume, the pole height and
the strain energy; :func:`step_fields` adds the largest principal stretch per node and the
mixed element's pressure per element.
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from snapjump_cli.viz.fields import nodal_stretch

__all__ = ["Steps", "path_steps", "step_fields", "STATE_NAMES"]

log = logging.getLogger(__name__)

#: The named states, in path order.
STATE_NAMES: tuple[str, ...] = ("start", "p_max", "upper", "lower")


@dataclass
class Steps:
    """A scene's states in path order (SI units; ``n`` steps).

    Attributes
    ----------
    U : (n, n_nodes, 2) displacement of every node [m]
    p_Pa, V_m3, y_pole_m, energy_J, arc_length : (n,) cavity pressure, the curve's volume (the
        cavity volume of a design, the supplied volume of a single cap), the lower pole's height,
        the strain energy, the arc length of the trace (NaN off the path)
    state : (n,) ``""`` or one of :data:`STATE_NAMES`
    on_path : (n,) whether the step lies on the traced path
    u : the model's free-dof vectors (scaled), for :func:`step_fields`
    p_scaled : the model's pressures (scaled)
    """

    U: np.ndarray
    p_Pa: np.ndarray
    V_m3: np.ndarray
    y_pole_m: np.ndarray
    energy_J: np.ndarray
    arc_length: np.ndarray
    state: list[str]
    on_path: np.ndarray
    u: list = field(default_factory=list, repr=False)
    p_scaled: list = field(default_factory=list, repr=False)

    def __len__(self) -> int:
        return len(self.state)

    def index(self, name: str) -> int | None:
        """The step of the named state (``None`` if the scene has none)."""
        return self.state.index(name) if name in self.state else None

    def columns(self) -> dict[str, list]:
        """The columns of the ``--csv`` file, in order: ``p_Pa``, ``V_m3``, ``y_pole_m``,
        ``strain_energy_J``, ``arc_length``, ``step``, ``state``, ``on_path``."""
        return {"p_Pa": list(self.p_Pa), "V_m3": list(self.V_m3), "y_pole_m": list(self.y_pole_m),
                "strain_energy_J": list(self.energy_J), "arc_length": list(self.arc_length),
                "step": list(range(len(self))), "state": list(self.state),
                "on_path": [int(b) for b in self.on_path]}


def _pressure_peak(res, pts: list, up) -> tuple[object | None, int]:
    """The loading path's pressure maximum: ``(state, k)`` with a state solved on the step after
    path point ``k``; ``(None, k)`` when it is path point ``k`` itself; ``(None, -1)`` when it is
    the upper state (the pressure still rises at ``V*``)."""
    from snapjump_cli.fe.axisym.snap import root_on_step

    st = res.states
    last = st.k_before if (up is not None and st.k_before is not None) else len(pts) - 1
    loading = pts[: last + 1] + ([up] if up is not None else [])
    k = int(np.argmax([pt.p for pt in loading]))
    if up is not None and k == len(loading) - 1 and up.tangent[1] >= 0:
        return None, -1
    k = min(k, last)
    # dp/ds changes sign from + to - on the step before or after the highest point
    for a in (k, k - 1):
        if 0 <= a < len(loading) - 1 and loading[a].tangent[1] > 0 >= loading[a + 1].tangent[1]:
            break
    else:
        return None, k
    b = loading[a + 1]
    if b.tangent[1] == 0.0:
        return (None, a + 1) if a + 1 <= last else (None, -1)
    peak = root_on_step(res.tracer, loading[a], b, loading[a - 1] if a > 0 else None,
                        lambda pt: pt.tangent[1], 1e-8, 30)
    if peak is b:  # no root better than the bracket's end was found: that end is the peak
        return (None, a + 1) if a + 1 <= last else (None, -1)
    return peak, a


def path_steps(res) -> Steps:
    """The states of a solved scene, in path order (see the module docstring).

    Parameters
    ----------
    res : :class:`snapjump_cli.fe.solve.SceneResult` with its model, path, states and tracer

    Returns
    -------
    Steps
    """
    model, path, st = res.model, res.path, res.states
    if model is None or path is None or st is None:
        raise ValueError("the scene result carries no traced path")
    if getattr(res, "air", None) is not None:  # inflated with air: the named snap is the air snap
        st = res.air.states
    pts = list(path.points)
    up = st.upper
    sV = res.curve_args[0][0]
    named: list[tuple[int, object, str]] = []  # (index of the path point it follows, state, name)
    peak, after = _pressure_peak(res, pts, up)
    if peak is not None:
        named.append((after, peak, "p_max"))
    if up is not None:
        named.append((st.k_before, up, "upper"))
    lower_on_path = st.lower is not None and st.lower_method == "path"
    if lower_on_path:
        named.append(((st.k_return or len(pts) - 1) - 1, st.lower, "lower"))
    seq: list[tuple[object, str, bool]] = []
    for i, pt in enumerate(pts):
        label = "start" if i == 0 else ("p_max" if (peak is None and i == after) else "")
        seq.append((pt, label, True))
        for k, state, name in sorted((n for n in named if n[0] == i), key=lambda n: n[1].s):
            seq.append((state, name, True))
    if st.lower is not None and not lower_on_path:
        seq.append((st.lower, "lower", False))
    L, S = model.L, model.S
    pole = int(model.mesh.node_sets["pole_lower"][0])
    U = np.stack([model.full_displacement(pt.u) * L for pt, _, _ in seq])
    X = model.X * L
    return Steps(
        U=U,
        p_Pa=np.array([pt.p for pt, _, _ in seq]) * S,
        V_m3=np.array([pt.zeta[0] * sV for pt, _, _ in seq]) * L**3,
        y_pole_m=X[pole, 1] + U[:, pole, 1],
        energy_J=np.array([model.energy(pt.u) for pt, _, _ in seq]) * S * L**3,
        arc_length=np.array([pt.s if on else math.nan for pt, _, on in seq], dtype=float),
        state=[name for _, name, _ in seq],
        on_path=np.array([on for _, _, on in seq], dtype=bool),
        u=[pt.u for pt, _, _ in seq],
        p_scaled=[pt.p for pt, _, _ in seq],
    )


def step_fields(res, steps: Steps, k: int) -> dict[str, np.ndarray]:
    """The fields of step ``k``: ``stretch`` (n_nodes,), the largest principal stretch at the
    nodes, and ``element_pressure_Pa`` (n_elements,), the mixed element's pressure
    ``kappa (theta - 1)`` (the mean stress, positive in tension) at the element centre."""
    model = res.model
    mesh = model.mesh
    X = mesh.nodes
    x = X + steps.U[k]
    out = {"stretch": nodal_stretch(X, x, mesh.elements, mesh.order)}
    lin = model.linearize(steps.u[k], steps.p_scaled[k])
    if lin is None or getattr(lin, "aux", None) is None:
        out["element_pressure_Pa"] = np.full(mesh.n_elements, np.nan)
    else:
        out["element_pressure_Pa"] = np.asarray(lin.aux)[:, 0] * model.S  # basis [1, xi, eta]: the centre value
    return out
