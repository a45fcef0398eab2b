"""The snap of an actuator inflated with air from a syringe (docs/air.md; paper S3, eqs 7-10).

The rubber's equilibrium depends only on the cavity pressure ``p``, so the equilibrium path
``(u, p)`` traced under volume control (:mod:`snapjump_cli.fe.continuation`) is the set of states under
air as well; what changes is the control. The syringe's dispensed volume is

    V_d(u, p) = (V(u) - V_cav0) + V0 - V_gas(p)          (eq 9; V_gas: :class:`snapjump_cli.fe.axisym.fluid.GasLaw`)

and the gas is a spring of compliance ``c(p) = -dV_gas/dp`` in series with the actuator. Hence:

* **The snap** comes at the first limit point of ``V_d`` along the path, where
  ``dV/ds + c dp/ds`` changes sign from + to -: between the pressure maximum (``V0 -> infinity``)
  and the volume limit ``V*`` (``V0 -> 0``). :class:`AirSnap` watches the trace for it and locates
  it as the root of ``dV_d/ds`` on a re-solved step (as :mod:`snapjump_cli.fe.axisym.snap` does for ``V*``).
* **The post-snap state** is at the same ``V_d``: on the path where it comes back to ``V_d*`` with
  ``dV_d/ds > 0`` (solved exactly there under the gas constraint), if that state is stable under
  the gas; else off the path by the fixed-volume path of :mod:`snapjump_cli.fe.axisym.lower_state` with the
  constraint ``V(u) + V0 - V_gas(p) = V_d*`` (:class:`GasControlled`).
* **Stability under the gas**: the stiffness is ``K_T + g g^T / c`` (``g = dV/du``), between
  pressure control (``c -> infinity``: ``K_T``) and volume control (``c -> 0``); its unstable
  modes are ``neg(K_T) - [c + g^T K_T^-1 g < 0]`` (:func:`snapjump_cli.fe.axisym.lower_state.constrained_instability`).
* **The energy released** is that of rubber and gas, ``dE = [W + G](upper) - [W + G](lower)``
  with the gas energy ``G(p)`` (:meth:`snapjump_cli.fe.axisym.fluid.GasLaw.energy`); along the path
  ``d(W + G)/ds = p dV_d/ds``, so it is also ``-integral p dV_d`` from the upper to the lower state
  (the area between the path in the ``(V_d, p)`` plane and the line ``V_d = V_d*``). Both are
  computed; they agree to the quadrature's accuracy when the lower state is on the path.
* **The actuator's volume change** during the snap is ``V_gas(p_after) - V_gas(p_before) > 0``
  (eq 9 at fixed ``V_d``; the printed eq 10 has the opposite sign).

One trace serves both fluids: it goes on until both snaps are characterised, and the water answers
are reported beside the air ones (``water_dE_J``, ``water_dy_pole_m``, ``water_h_imp_m``).
"""
from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from snapjump_cli.fe.continuation import hermite
from snapjump_cli.fe.continuation import Path, PathPoint, Tracer
from snapjump_cli.fe.axisym.fluid import FluidSettings, GasLaw
from snapjump_cli.fe.axisym.lower_state import LowerState, constrained_instability, find_lower_state
from snapjump_cli.fe.axisym.metrics import path_p_dV, snap_metrics, snap_sequence
from snapjump_cli.fe.axisym.snap import SnapStates, SnapTracker, root_on_step
from snapjump_cli.schema import AIR, AIR_SNAP_KEYS, columns

log = logging.getLogger(__name__)

__all__ = ["GasControlled", "AirSnap", "fluid_keys", "AIR_KEYS"]

#: The row keys of air (:data:`snapjump_cli.schema.AIR`).
AIR_KEYS: tuple[str, ...] = columns(AIR)

SNAP_DONE = "snap characterised"


def fluid_keys(fluid: FluidSettings | None) -> dict:
    """The :data:`AIR_KEYS` of a water run: ``fluid = "water"``, the others ``None``."""
    out = {k: None for k in AIR_KEYS}
    out["fluid"] = "water" if fluid is None or not fluid.is_air else "air"
    return out


class GasControlled:
    """The FE model with the syringe's dispensed volume as its first path measure: ``zeta_0 =
    V(u) + V0 - V_gas(p)`` (``V_d`` up to the constant ``V_cav0``), ``d zeta_0 / dp = c(p)``.

    A :class:`~snapjump_cli.fe.continuation.Tracer` on it (Python corrector) solves states at a given
    ``V_d`` (``target=(0, value)``) and judges their stability under the gas
    (:func:`snapjump_cli.fe.axisym.lower_state.constrained_instability`). Scaled units, as the model.
    """

    def __init__(self, model, gas: GasLaw) -> None:
        self.model, self.gas, self.n = model, gas, model.n

    def linearize(self, u: np.ndarray, p: float, stiffness: bool = True, aux: np.ndarray | None = None):
        return self.model.linearize(u, p, stiffness, aux=aux)

    def measures(self, u: np.ndarray, p: float, lin=None):
        z, dz_du, dz_dp = self.model.measures(u, p, lin)
        z[0] += self.extra_volume(p)
        dz_dp = dz_dp.copy()
        dz_dp[0] = self.compliance(p)
        return z, dz_du, dz_dp

    def extra_volume(self, p: float) -> float:
        """``V0 - V_gas(p)``: the dispensed volume not in the cavity."""
        return float(self.gas.expelled(p))

    def compliance(self, p: float) -> float:
        return float(self.gas.compliance(p))

    def potential(self, E: float, p: float) -> float:
        """The energy of rubber (``E``) and gas at the pressure ``p``."""
        return E + float(self.gas.energy(p))

    def energy(self, u: np.ndarray) -> float:
        return self.model.energy(u)


class AirSnap:
    """The snap under air along a trace of the equilibrium path.

    Parameters
    ----------
    fluid : the air setting (SI)
    tracer : the tracer of the pressure-volume path (its problem is the FE model)
    post_snap_steps : steps after the limit of ``V_d`` within which the path must come back to it

    Use :meth:`watch` as the trace's stop criterion (around the water :class:`SnapTracker`), then
    :meth:`lower_state` and :meth:`metrics`.
    """

    def __init__(self, fluid: FluidSettings, tracer: Tracer, post_snap_steps: int) -> None:
        model = tracer.pb
        self.fluid = fluid
        self.gas = fluid.gas().scaled(model.L, model.S)
        self.tracer = tracer
        self.sV, self.sp = float(tracer.sc[0]), float(tracer.sc[1])
        self.control = Tracer(GasControlled(model, self.gas), dataclasses.replace(tracer.cfg, fused=False))
        self.post_snap_steps = post_snap_steps
        self.states = SnapStates()
        self.gave_up = False
        self._water_done = False

    # ---- the dispensed volume along the path (units of the trace's volume scale) ---------------
    def vd(self, pt: PathPoint) -> float:
        """``V_d`` of a path point (up to ``V_cav0``), in units of the volume scale."""
        return float(pt.zeta[0]) + float(self.gas.expelled(pt.p)) / self.sV

    def rate(self, pt: PathPoint) -> float:
        """``dV_d/ds`` at a path point, in units of the volume scale."""
        return float(pt.tangent[0]) + float(self.gas.compliance(pt.p)) * self.sp / self.sV * float(pt.tangent[1])

    def _hermite_guess(self, a: PathPoint, b: PathPoint, value: float | None) -> float | None:
        """Arc length from ``a`` where the cubic Hermite ``V_d(s)`` takes ``value`` (``None``: where
        its derivative vanishes); ``None`` if nowhere inside the step."""
        h = b.s - a.s
        t = hermite.first_root(self.vd(a), self.rate(a) * h, self.vd(b), self.rate(b) * h, value)
        return None if t is None else t * h

    # ---- the stop criterion -------------------------------------------------------------------
    def watch(self, water: SnapTracker):
        """The trace's stop criterion: the water tracker's, going on until the air snap is
        characterised too (or its budget is spent)."""

        def stop(path: Path) -> str | None:
            reason = water(path)
            self._step(path)
            if water.full:
                return reason
            if reason == SNAP_DONE:
                self._water_done = True
            elif reason:
                return reason  # a bound, or the water snap's post-snap budget
            if self._water_done and (self.states.lower is not None or self.gave_up):
                return SNAP_DONE
            return None

        return stop

    def _step(self, path: Path) -> None:
        st, pts, tr = self.states, path.points, self.tracer
        new, prev = pts[-1], pts[-2]
        prev2 = pts[-3] if len(pts) > 2 else None
        if st.upper is None:
            if self.rate(prev) > 0 and self.rate(new) <= 0:
                st.k_before = len(pts) - 2
                st.upper = root_on_step(tr, prev, new, prev2, self.rate, 1e-7, 30,
                                        s0=self._hermite_guess(prev, new, None))
                log.debug("limit of the dispensed volume: p = %.6g", st.upper.p)
        elif st.lower is None and not self.gave_up:
            T = self.vd(st.upper)
            if self.rate(new) > 0 and self.vd(new) >= T and self.vd(prev) < T:
                st.k_return = len(pts) - 1
                st.lower = self._locate(prev, new, T, prev2)
                if st.lower is not None:
                    st.lower_method = "path"
            elif len(pts) - 1 - st.k_before > self.post_snap_steps:
                self.gave_up = True

    def _locate(self, a: PathPoint, b: PathPoint, T: float, a_prev: PathPoint | None) -> PathPoint | None:
        """The path point at ``V_d = T`` between ``a`` and ``b``, polished at exactly ``T`` under the
        gas constraint (its arc length kept: it lies on the path)."""
        tol = 1e-8 * max(1.0, abs(T))
        best = root_on_step(self.tracer, a, b, a_prev, lambda pt: self.vd(pt) - T, tol, 40,
                            s0=self._hermite_guess(a, b, T))
        pt = self._polish(best, T)
        if pt is None:
            return None
        pt.s = best.s
        return pt

    def _polish(self, start: PathPoint, T: float) -> PathPoint | None:
        """The equilibrium at ``V_d = T`` from ``start`` (Newton under the gas constraint), with its
        tangent in the trace's measures."""
        tr = self.tracer
        res = self.control.correct(start.u.copy(), start.p, None, None, 0.0, target=(0, T))
        if res is None:
            return None
        lin, it = res
        t, v, q, z = tr.tangent(lin, (start.tangent, tr.alpha * start.du_ds))
        return PathPoint(lin.u, lin.p, z, t, v, q, start.s, it, tr.last_det_sign, tr.last_n_neg)

    # ---- after the trace ----------------------------------------------------------------------
    def lower_state(self, points: list[PathPoint], why: str) -> LowerState:
        """The post-snap state under air: on the path if it came back to ``V_d*`` on a branch
        stable under the gas, else off the path at fixed ``V_d`` (the fixed-volume path of
        :func:`snapjump_cli.fe.axisym.lower_state.find_lower_state` under the gas constraint). Sets
        ``states.lower`` and ``states.lower_method``."""
        st = self.states
        if st.upper is None:
            return LowerState(None)
        if st.lower is None and self.gave_up:
            why = f"the path did not return to V_d* within {self.post_snap_steps} steps"
        low = find_lower_state(self.tracer, st, points, why, control=self.control)
        st.lower, st.lower_method = low.state, low.method
        return low

    def unstable_modes(self, pt: PathPoint) -> int:
        """Unstable modes of a state under the gas (-1: unknown)."""
        lin = self.tracer.pb.linearize(pt.u, pt.p)
        return constrained_instability(self.control, lin) if lin is not None else -1

    def metrics(self, model, path: Path, water: dict, low: LowerState, scales: tuple[float, float, float]) -> dict:
        """The metrics of an air run: those of :func:`snapjump_cli.fe.axisym.metrics.snap_metrics` for the air
        snap (``dE_J`` of rubber and gas), the :data:`AIR_KEYS`, and the water run's diagnostics."""
        st = self.states
        L, S = model.L, model.S
        E_unit, V_unit = S * L**3, L**3
        out = dict(water)
        out.update(fluid_keys(self.fluid))
        out.update(air_V0_m3=self.fluid.V0_m3, air_gamma=float(self.fluid.gamma), air_p0_Pa=float(self.fluid.p0),
                   water_dE_J=water["dE_J"], water_dy_pole_m=water["dy_pole_m"], water_h_imp_m=water["h_imp_m"])
        air = snap_metrics(model, path, st, scales, lower_solver=low.solver, lower_note=low.note)
        for k in AIR_SNAP_KEYS:
            out[k] = air.get(k)
        if st.upper is None:
            return out
        up, lo = st.upper, st.lower
        g = self.gas
        dE_gas = float(g.energy(up.p) - g.energy(lo.p))
        dE_rubber = air["dE_energy_J"] / E_unit
        dE = dE_rubber + dE_gas
        dE_path = math.nan
        if st.lower_method == "path":  # -integral p dV_d along the path from the upper to the lower state
            seq = [dataclasses.replace(pt, zeta=np.r_[self.vd(pt), pt.zeta[1:]], tangent=np.r_[self.rate(pt), pt.tangent[1:]])
                   for pt in snap_sequence(path, st)]
            dE_path = -path_p_dV(seq, self.sV, self.sp)
        V_up, V_lo = up.zeta[0] * self.sV, lo.zeta[0] * self.sV
        out.update(
            dE_J=dE * E_unit, dE_energy_J=dE * E_unit, dE_norm=dE,
            dE_path_J=dE_path * E_unit if math.isfinite(dE_path) else None,
            dE_rel_diff=abs(dE - dE_path) / max(abs(dE), 1e-300) if math.isfinite(dE_path) else None,
            dE_rubber_J=dE_rubber * E_unit, dE_gas_J=dE_gas * E_unit,
            p_before_Pa=up.p * S, p_after_Pa=lo.p * S,
            V_disp_m3=(self.vd(up) * self.sV - self.V_cav0(model)) * V_unit,
            dV_snap_m3=(V_lo - V_up) * V_unit,
            dV_snap_eq9_m3=float(g.volume(lo.p) - g.volume(up.p)) * V_unit,
        )
        return out

    @staticmethod
    def V_cav0(model) -> float:
        """The cavity volume of the stress-free state (scaled)."""
        return model.volume(np.zeros(model.n))

    def dispensed(self, V_m3, p_Pa, model) -> np.ndarray:
        """The dispensed volume [m^3] at cavity volumes ``V_m3`` and pressures ``p_Pa`` (SI arrays)."""
        gas = self.fluid.gas()
        return np.asarray(V_m3, dtype=float) - self.V_cav0(model) * model.L**3 + gas.expelled(np.asarray(p_Pa, dtype=float))

    def curve(self, model, path: Path, scales: tuple[float, float, float], V0: float) -> dict:
        """The dispensed volume along the traced path (``V_disp_m3``) and the air snap's states
        (``air_snap_Vd_m3``, ``air_snap_V_m3``, ``air_snap_p_Pa``: upper, path points, lower), SI."""
        L, S = model.L, model.S
        out = {"V_disp_m3": (np.array([self.vd(pt) for pt in path.points]) * self.sV - V0) * L**3,
               "air_V0_m3": self.fluid.V0_m3}
        st = self.states
        if st.upper is not None and st.lower is not None:
            seq = snap_sequence(path, st)
            out["air_snap_Vd_m3"] = (np.array([self.vd(pt) for pt in seq]) * self.sV - V0) * L**3
            out["air_snap_V_m3"] = np.array([pt.zeta[0] for pt in seq]) * self.sV * L**3
            out["air_snap_p_Pa"] = np.array([pt.p for pt in seq]) * S
        return out
