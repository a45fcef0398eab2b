"""The followed designs' landing and upper states against mirror-antisymmetric perturbations.

    .venv/bin/python -m bench.mirror_check --sample bench/harmonics_sample/follow_strata.yaml --rows 0 1 ...

For each row of a sweep config's design list (its mesh and solver settings, as
:mod:`bench.profile.follow` takes them): the axisymmetric solve, the harmonic check, the followed
answer (``followed_metrics`` with the config's ``follow_mode``, within its ``time_limit_s``), then
:func:`snapjump_cli.fe.stability.mirror.mirror_stability` at the answer's branch's lower state (where
the actuator lands) and upper state. A branch that keeps only the multiples of ``n_c >= 2`` is
lifted first into the model of every harmonic ``0..N`` (:func:`snapjump_cli.fe.branch.secondary.full_model`).

One JSON line per row on stdout: the design, what the follow found, and per state the
antisymmetric block's unstable count (``n_unstable``), smallest eigenvalue (``smallest``,
``mu_i / R_i^2``), the modes excluded and their quotients, and the state's largest harmonic
amplitude (``asym_amp``, scaled by the inner radius: 0 for an axisymmetric state).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.profile.follow import scenes
from snapjump_cli.fe.branch.followed import followed_metrics
from snapjump_cli.fe.limits import TimeLimitExceeded, time_limit
from snapjump_cli.fe.solve import solve_scene
from snapjump_cli.fe.stability.harmonics import check_harmonics
from snapjump_cli.fe.stability.mirror import MirrorOperator, mirror_stability


def asym_amplitude(mh, u: np.ndarray) -> float:
    """The largest nodal amplitude of a harmonic ``n >= 1`` of the state (scaled)."""
    return max((float(np.abs(mh.harmonic_part(u, int(n))).max()) for n in mh.hn[1:]), default=0.0)


def check_state(op: MirrorOperator, mh, pt) -> dict[str, Any]:
    """The mirror check of one state, with its asymmetry."""
    out = mirror_stability(op, pt.u, pt.p).as_dict()
    out["asym_amp"] = asym_amplitude(mh, pt.u)
    out["V"] = float(mh.volume(pt.u))  # scaled (R_i^3)
    out["p"] = float(pt.p)  # scaled (mu_i)
    return out


def one_row(label: str, scene, mesh, solver) -> dict[str, Any]:
    """Solve, follow and check one design."""
    t0 = time.process_time()
    res = solve_scene(scene, mesh, solver)
    chk = check_harmonics(res, solver.harmonics)
    row: dict[str, Any] = {"design": label,
                           "scene": dataclasses.asdict(scene) if dataclasses.is_dataclass(scene) else repr(scene),
                           "asym_first": bool(chk.asym_first), "asym_n": chk.asym_n}
    if not chk.asym_first:
        row["note"] = "no harmonic unstable before V*: not followed"
        row["cpu_s"] = time.process_time() - t0
        return row
    try:
        with time_limit(solver.time_limit_s):
            ans = followed_metrics(res, chk, mode=solver.follow_mode)
    except TimeLimitExceeded as exc:
        row["note"] = f"at the time limit: {exc}"
        row["cpu_s"] = time.process_time() - t0
        return row
    row["cpu_follow_s"] = time.process_time() - t0
    fr = ans.branch
    row.update({k: ans.values.get(k) for k in ("followed", "follow_kind", "follow_note", "follow_sec_n",
                                               "lower_state_method")})
    if fr is None or fr.states is None:
        row["note"] = "no followed branch"
        row["cpu_s"] = time.process_time() - t0
        return row
    mh = fr.model
    row["harmonics"] = [int(h) for h in mh.hn]
    row["lower_note"] = fr.lower_note
    lift = None
    if not np.array_equal(mh.hn, np.arange(len(mh.hn))):
        from snapjump_cli.fe.branch.secondary import full_model, lift as lift_state

        full = full_model(mh)
        lift = (full, lift_state)
        row["lifted_to"] = [int(h) for h in full.hn]
    t1 = time.process_time()
    model = lift[0] if lift else mh
    op = MirrorOperator(model)
    row["ndof_mirror"] = op.ndof
    for name in ("lower", "upper"):
        pt = getattr(fr.states, name, None)
        if pt is None:
            row[name] = None
            continue
        if lift:
            pt = dataclasses.replace(pt, u=lift[1](mh, lift[0], pt.u))
        row[name] = check_state(op, model, pt)
    row["cpu_mirror_s"] = time.process_time() - t1
    row["cpu_s"] = time.process_time() - t0
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.mirror_check", description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=Path, required=True,
                    help="a sweep config (e.g. bench/harmonics_sample/follow_strata.yaml)")
    ap.add_argument("--rows", type=int, nargs="+", required=True, help="rows of its design list")
    args = ap.parse_args(argv)
    for label, scene, mesh, solver in scenes([], args.sample, args.rows):
        try:
            row = one_row(label, scene, mesh, solver)
        except Exception as exc:  # one design's failure must not lose the others' lines
            row = {"design": label, "error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(row, default=lambda o: o.item() if hasattr(o, "item") else str(o)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
