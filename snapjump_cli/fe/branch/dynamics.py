"""The snap as a damped motion at fixed volume: which stable state the actuator reaches.

Where the actuator mode and the reference land a followed snap on different stable states
(docs/harmonics.md section 10.8), the physical answer is the state that the rubber's motion
reaches from the unstable state. :func:`damped_snap` integrates

    M u'' + c M u' + f_int(u) - p dV/du = 0,    V(u) = V*

(the cavity's water neither enters nor leaves during the snap; ``p`` is the constraint's
multiplier) from the upper state displaced by a small amplitude along its unstable mode, with
Newmark's rule (``gamma = 0.6``: the highest frequencies of the mesh damped numerically, the slow
motion by the stated ``c``; adaptive steps, cut where Newton does not converge), until the motion
has died out, and polishes the state it comes to rest at by Newton's method at fixed volume.

Units are the model's: lengths ``/ L``, stresses ``/ S``, so time is in ``t0 = L sqrt(rho / S)``
(``rho`` the rubber's density; its value only sets the time scale). ``M`` is the lumped (HRZ)
mass of the 3D body in the model's Fourier amplitudes: the weight of harmonic 0 is 1 and that of a
harmonic ``n >= 1`` is 1/2 (the mean of ``cos^2 n phi``). ``c`` is mass-proportional damping, given
as a damping ratio ``zeta`` of a reference angular frequency ``omega`` (``c = 2 zeta omega``).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from snapjump_cli.fe.axisym.lower_state import constrained_instability
from snapjump_cli.fe.continuation import PathPoint, Tracer

log = logging.getLogger(__name__)

__all__ = ["lumped_mass", "lowest_frequency", "DampedSnap", "damped_snap"]


#: Newmark's parameters: ``gamma > 1/2`` damps the highest frequencies of the mesh (numerical
#: dissipation of order ``gamma - 1/2`` per step at ``omega dt >> 1``, negligible for the slow
#: motion that decides where the snap ends: a ``zeta`` of ``(gamma - 1/2) omega dt / 2`` there,
#: 0.008 at 40 steps per period) so that the steps can follow the slow motion.
NEWMARK_GAMMA = 0.6
NEWMARK_BETA = 0.25 * (NEWMARK_GAMMA + 0.5) ** 2


def lumped_mass(mh) -> np.ndarray:
    """The lumped mass of the multi-harmonic model ``mh`` per free dof (unit density)."""
    M = mh.base
    # HRZ lumping (the consistent mass's diagonal scaled to each element's mass): positive at
    # every node, where the row sums of a Q9 element weighted by the radius vanish on the axis
    diag = np.einsum("eq,qa->ea", M.Wq, M.N_ref**2)
    elem = diag * (M.Wq.sum(axis=1) / diag.sum(axis=1))[:, None]
    m_node = np.zeros(M.X.shape[0])
    np.add.at(m_node, M.conn, elem)
    w = np.full(mh.nc, 0.5)
    w[:2] = 1.0
    free = mh.dofmap >= 0
    out = np.zeros(mh.n)
    np.add.at(out, mh.dofmap[free], (m_node[:, None] * w[None, :] * mh.coef**2)[free])
    return out


def lowest_frequency(tracer: Tracer, u: np.ndarray, p: float) -> float:
    """The lowest natural angular frequency (``1 / t0``) at fixed volume of the state ``(u, p)`` of
    the tracer's multi-harmonic model, with :func:`lumped_mass` (dense eigenvalues: for the
    arbiter's few designs, not for a sweep)."""
    import scipy.linalg as sl

    mh = tracer.pb
    lin = mh.linearize(u, p)
    K = lin.stiffness().toarray()
    _, dz_du, _ = tracer.zeta(u, p, lin)
    m = lumped_mass(mh)
    s = 1.0 / np.sqrt(m)
    Ks = K * s[:, None] * s[None, :]
    g = dz_du[0] * s
    g = g / np.linalg.norm(g)
    Q = sl.null_space(g[None, :])
    lam = sl.eigh(Q.T @ Ks @ Q, eigvals_only=True, subset_by_index=[0, 0])[0]
    return math.sqrt(max(lam, 0.0))


@dataclass
class DampedSnap:
    """What :func:`damped_snap` found: the state it came to rest at (``None``: it did not), the
    time steps taken, the time (in ``t0``), the largest kinetic energy and the message."""

    state: PathPoint | None
    steps: int
    time: float
    kinetic_max: float
    message: str


def damped_snap(tracer: Tracer, upper: PathPoint, direction: np.ndarray, omega: float, zeta: float = 0.1,
                kick: float = 1e-3, steps_per_period: int = 40, max_periods: float = 400.0,
                rest: float = 1e-10) -> DampedSnap:
    """Integrate the snap at the volume of ``upper`` from ``upper`` displaced along ``direction``.

    Parameters
    ----------
    tracer : the tracer of the multi-harmonic model (``tracer.pb``) whose state ``upper`` is
    upper : the unstable state the snap starts from (its volume is held)
    direction : the unstable mode (scaled to a largest entry of ``kick`` times the largest
        displacement of ``upper``)
    omega : the reference angular frequency (``1 / t0``): the time step is ``2 pi / omega /
        steps_per_period`` and the damping ``c = 2 zeta omega``
    zeta : damping ratio at ``omega``
    max_periods : time limit, in periods of ``omega``
    rest : the motion has died out when the kinetic energy is below ``rest`` times its largest
        value and the equilibrium residual is below the tracer's tolerance scale

    Returns
    -------
    DampedSnap
    """
    pb = tracer.pb
    m = lumped_mass(pb)
    c = 2.0 * zeta * omega
    dt = 2.0 * math.pi / omega / steps_per_period
    beta, gamma = NEWMARK_BETA, NEWMARK_GAMMA
    V_star = float(upper.zeta[0])
    d = direction / float(np.abs(direction).max())
    u = upper.u + kick * max(float(np.abs(upper.u).max()), 1e-12) * d
    p = upper.p
    v = np.zeros(pb.n)
    if pb.linearize(u, p) is None:
        return DampedSnap(None, 0, 0.0, 0.0, "the kicked state lies outside the material domain")
    a = np.zeros(pb.n)  # at rest: the kicked state is an equilibrium to second order in the kick
    K_max, t, T_end, dt0 = 0.0, 0.0, max_periods * 2.0 * math.pi / omega, dt
    k = 0
    while t < T_end:
        k += 1
        shift = m * (1.0 / (beta * dt * dt) + c * gamma / (beta * dt))
        step = _newmark_step(tracer, m, c, dt, shift, V_star, u, v, a, p, beta, gamma)
        if step is None:  # a step Newton cannot take: halve it (the snap itself is fast)
            dt *= 0.5
            if dt < 1e-6 * dt0:
                return DampedSnap(None, k, t, K_max, f"time step cut below 1e-6 of 2 pi / omega / {steps_per_period} at t = {t:.4g} t0")
            continue
        u, v, a, p, its = step
        t += dt
        if its <= 5:
            dt = min(dt0, 1.5 * dt)
        kin = 0.5 * float(v @ (m * v))
        K_max = max(K_max, kin)
        if log.isEnabledFor(logging.DEBUG):  # (the energy is one more element pass)
            log.debug("step %d: t=%.5g dt=%.3g its=%d kinetic=%.3e E=%.10g", k, t, dt, its, kin, pb.energy(u))
        if K_max > 0.0 and kin < rest * K_max and t > 2.0 * math.pi / omega:
            got = tracer.correct(u, p, None, None, 0.0, target=(0, V_star))
            if got is None:
                continue
            lin, it = got
            if constrained_instability(tracer, lin) != 0:
                continue
            tt, vv, q, zz = tracer.tangent(lin, (upper.tangent, tracer.alpha * upper.du_ds))
            st = PathPoint(lin.u, lin.p, zz, tt, vv, q, float("nan"), it)
            return DampedSnap(st, k, t, K_max, f"at rest after {k} steps ({t:.4g} t0)")
    return DampedSnap(None, k, t, K_max, f"still moving after {max_periods:g} periods")


def _newmark_step(tracer, m, c, dt, shift, V_star, u_n, v_n, a_n, p, beta, gamma):
    """One Newmark step at fixed volume: ``(u, v, a, p, Newton iterations)``, or ``None`` if Newton
    does not converge in 12 iterations (or leaves the material domain)."""
    pb = tracer.pb
    u = u_n + dt * v_n + dt * dt * (0.5 - beta) * a_n
    for it in range(12):
        lin = pb.linearize(u, p)
        if lin is None:
            return None
        a = (u - u_n - dt * v_n) / (beta * dt * dt) - (1.0 / (2.0 * beta) - 1.0) * a_n
        v = v_n + dt * ((1.0 - gamma) * a_n + gamma * a)
        res = m * a + c * m * v + lin.R
        z, dz_du, _ = tracer.zeta(u, p, lin)
        solver = lin.factor(dz_du[0], 0.0, shift=shift)
        if solver is None:
            return None
        x = solver.solve(np.concatenate([-res, [-float(z[0] - V_star)]]))
        if not np.all(np.isfinite(x)):
            return None
        u = u + x[:-1]
        p = p + x[-1]
        if float(np.abs(x[:-1]).max()) < 1e-10 * max(1.0, float(np.abs(u).max())):
            a = (u - u_n - dt * v_n) / (beta * dt * dt) - (1.0 / (2.0 * beta) - 1.0) * a_n
            v = v_n + dt * ((1.0 - gamma) * a_n + gamma * a)
            return u, v, a, p, it + 1
    return None
