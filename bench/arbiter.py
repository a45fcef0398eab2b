"""Which stable state a followed snap reaches: the damped motion at fixed volume as the arbiter
between the actuator mode and the reference (issue 36, item 3; docs/harmonics.md section 10.8).

    .venv/bin/python -m bench.arbiter --design 6.2 75 5 82 5.8 --nt 2 --aspect 8 [--zeta 0.05 0.2 1]

solves the design (Q9 at the given mesh, harmonic check n <= 4), takes its followed answer in both
follow modes and, if they land on different states (or with ``--always``), integrates the snap
from the upper state displaced along its unstable mode by 1e-3 of its largest displacement, both
ways (the two signs are mirror images for n = 1), for each damping ratio, with
:func:`snapjump_cli.fe.branch.dynamics.damped_snap`. The reference frequency ``omega`` is the
lowest natural frequency at fixed volume of the reference's landing state (the lumped mass; dense
eigenvalues). Prints, per run, the state it comes to rest at: its distance to each mode's landing
state (or that state's mirror image), its released energy, the steps and the time in ``t0``.
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from snapjump_cli.fe.branch.dynamics import damped_snap, lowest_frequency
from snapjump_cli.fe.continuation import PathPoint
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.branch.model import transfer
from snapjump_cli.fe.branch.trace import axisym_crossings
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.geometry.caps import Design
from snapjump_cli.settings import MeshSettings, SolverSettings


def mirror(mh, u: np.ndarray) -> np.ndarray:
    """The mirror image of a state (rotated by pi about the axis: odd harmonics change sign)."""
    A = mh.amplitudes(u)
    for k, n in enumerate(mh.hn):
        if n % 2:
            o = 2 + 3 * (k - 1)
            A[:, o:o + 3] *= -1.0
    return mh.free_vector(A)


def past_bifurcation(res, fr, V1: float) -> PathPoint:
    """The state at scaled volume ``V1`` (just past the bifurcation of ``fr``, a subcritical
    branch) on the path that the branch leaves, as a state of ``fr``'s model: the axisymmetric
    path's, or for a secondary bifurcation (``fr.parent``) the parent branch's crossing of ``V1``
    (:func:`~snapjump_cli.fe.branch.trace.axisym_crossings` on the branch) nearest the bifurcation."""
    mh, tr, up = fr.model, fr.tracer, fr.states.upper
    if fr.parent is None:
        q = next(q for _, q in axisym_crossings(res, V1))
        U, p = mh.embed(q.u), q.p
    else:
        par = fr.parent
        Vp = V1 * float(tr.sc[0]) / float(par.tracer.sc[0])
        U_b = transfer(mh, par.model, up.u, strict=False)
        found = [q for _, q in axisym_crossings(par, Vp) if q is not None]
        if not found:
            raise SystemExit(f"the parent branch has no state at V = {Vp:.6g} (scaled)")
        q = min(found, key=lambda q: float(np.linalg.norm(q.u - U_b)))
        U, p = transfer(par.model, mh, q.u), q.p
    lin = mh.linearize(U, p)
    t_, v_, q_, z_ = tr.tangent(lin, (up.tangent, tr.alpha * up.du_ds))
    return PathPoint(U, p, z_, t_, v_, q_, float("nan"), 0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.arbiter", description=__doc__.split("\n\n")[0])
    ap.add_argument("--design", type=float, nargs=5, required=True, metavar=("ETA_I", "THETA_I", "ETA_O", "THETA_O", "MU"))
    ap.add_argument("--nt", type=int, default=2)
    ap.add_argument("--aspect", type=float, default=3.0)
    ap.add_argument("--zeta", type=float, nargs="+", default=[0.05, 0.2, 1.0])
    ap.add_argument("--always", action="store_true", help="integrate even if both modes land on the same state")
    ap.add_argument("--past", type=float, default=1e-3,
                    help="a subcritical snap starts at (1 + PAST) times the bifurcation's volume (default 1e-3)")
    a = ap.parse_args(argv)
    res = solve_scene(Design(*a.design), MeshSettings(order=2, nt=a.nt, aspect=a.aspect), SolverSettings(harmonics=4))
    chk = check_harmonics(res, 4)
    if not chk.asym_first:
        print("the design stays axisymmetric up to V*")
        return 0
    ans = {m: followed_metrics(res, chk, mode=m) for m in ("actuator", "full")}
    fr = ans["full"].branch
    mh, tr, up = fr.model, fr.tracer, fr.states.upper
    lows = {m: ans[m].branch.states.lower.u for m in ans}
    E_up = mh.energy(up.u)
    dist = float(np.linalg.norm(lows["actuator"] - lows["full"]) / np.linalg.norm(lows["full"]))
    print(json.dumps({m: {"dE_J": ans[m].values["dE_J"], "dy_pole_m": ans[m].values["dy_pole_m"],
                          "note": ans[m].values["follow_note"]} for m in ans}, indent=1))
    print(f"landing states' distance {dist:.3g}; dofs {mh.n}")
    if dist < 1e-6 and not a.always:
        return 0
    omega = lowest_frequency(tr, fr.states.lower.u, fr.states.lower.p)
    print(f"reference frequency omega = {omega:.4g} / t0 (period {2 * math.pi / omega:.4g} t0)")
    mode = fr.path.points[0].du_ds if fr.kind == "subcritical" else up.du_ds
    start = up
    if fr.kind == "subcritical":
        # the bifurcation is degenerate (the energy falls along its mode only at fourth order): the
        # motion starts from the state just past it on the path it leaves (the axisymmetric path,
        # or for a secondary bifurcation the branch of n_c >= 2), where the mode is unstable
        start = past_bifurcation(res, fr, float(up.zeta[0]) * (1.0 + a.past))
        print(f"started at V = (1 + {a.past:g}) V_b on the "
              + ("axisymmetric path" if fr.parent is None else f"branch of harmonic {int(fr.parent.bif.n)}"))
    print("| zeta | sign | rests at | steps | time (t0) | dE / reference dE | distance to actuator's / reference's landing (or mirror) |")
    print("|---|---|---|---|---|---|---|")
    dE_ref = E_up - mh.energy(lows["full"])
    # (each state it comes to rest at is compared at its own volume, (1 + PAST) V_b for a subcritical snap:
    # the landing states move by O(PAST) from those at V_b)
    for z in a.zeta:
        for sgn in (1.0, -1.0):
            t0 = time.process_time()
            ds = damped_snap(tr, start, sgn * mode, omega, zeta=z)
            cpu = time.process_time() - t0
            if ds.state is None:
                print(f"| {z:g} | {sgn:+.0f} | {ds.message} | {ds.steps} | {ds.time:.4g} | | |")
                continue
            u = ds.state.u
            d = {m: min(np.linalg.norm(u - w), np.linalg.norm(u - mirror(mh, w))) / np.linalg.norm(w)
                 for m, w in lows.items()}
            print(f"| {z:g} | {sgn:+.0f} | {ds.message} | {ds.steps} | {ds.time:.4g} | "
                  f"{(E_up - mh.energy(u)) / dE_ref:.6f} | {d['actuator']:.2e} / {d['full']:.2e} | ({cpu:.1f} CPU-s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
