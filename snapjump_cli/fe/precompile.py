"""The kernels compiled ahead of time with the signatures a solve uses (``make install`` runs
``python -m snapjump_cli.fe.precompile --if-stale``).

:func:`collect_signatures` solves the scenes whose kernels a run calls; the compilation itself,
the stamp that records what a build was made for, and the guard that uses a build only on the
CPU and for the kernel sources it was made for are :mod:`snapjump_kernels.aot`'s.
"""
from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path
from typing import Any

from snapjump_kernels import aot

__all__ = ["collect_signatures", "warm_followed", "main"]


def collect_signatures() -> dict[str, dict[str, Any]]:
    """Solve the scenes whose kernels a run calls (a cap, a design with its lower state off the
    path, the harmonic check) and return the dispatchers of :data:`snapjump_kernels.calls.KERNELS`
    that were called, per kernel module (each with the signatures it was called with)."""
    from numba.core.registry import CPUDispatcher

    from snapjump_cli.fe.stability.harmonics import check_harmonics
    from snapjump_cli.fe.solve import solve_checked, solve_scene
    from snapjump_cli.geometry.caps import CapScene, Design
    from snapjump_cli.settings import MeshSettings, SolverSettings

    solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc="clamped"), MeshSettings(), SolverSettings())
    solve_scene(CapScene(theta_deg=60.0, eta=30.0, bc="clamped"), MeshSettings(order=1), SolverSettings())
    off_path = Design(eta_i=5.6, theta_i_deg=80.0, eta_o=15.0, theta_o_deg=82.0, mu_ratio=5.8)  # grid-1543
    res = solve_checked(off_path, MeshSettings(order=2, nt=2, aspect=3.0), SolverSettings())
    check_harmonics(res, 1)
    from snapjump_kernels.calls import KERNELS

    found: dict[str, dict[str, Any]] = {}
    for modname, names in KERNELS.items():
        mod = importlib.import_module(f"snapjump_kernels.{modname}")
        for name in names:
            obj = getattr(mod, name)
            if isinstance(obj, CPUDispatcher) and obj.nopython_signatures:
                found.setdefault(modname, {})[name] = obj
    return found


def warm_followed() -> None:
    """Compile the JIT kernels of a followed branch (:data:`snapjump_kernels.calls.JIT_KERNELS`)
    into numba's cache: the multi-harmonic model of a small cap linearised and factorised at rest
    (and its mirror-antisymmetric block formed),
    without a solve (so without compiling the axisymmetric kernels, which the ahead-of-time build
    compiles). ``make install`` runs it on the second core beside that build, so that the first
    followed solve does not pay the compilation."""
    import numpy as np

    from snapjump_cli.fe.branch.model import MultiHarmonicModel
    from snapjump_cli.fe.solve import build_model
    from snapjump_cli.geometry.caps import CapScene
    from snapjump_cli.mesh.build import mesh_scene
    from snapjump_cli.settings import MeshSettings, SolverSettings

    scene = CapScene(theta_deg=30.0, eta=50.0, bc="clamped")
    model = build_model(scene, mesh_scene(scene, MeshSettings(nt=1, aspect=2.0)), SolverSettings())
    mh = MultiHarmonicModel(model, [0, 2, 4])
    u = np.zeros(mh.n)
    mh.energy(u)
    mh.residual(u, 0.0)
    lin = mh.linearize(u, 0.0)
    lin.factor(lin.g, 0.0)
    lin.factor(lin.g, 0.0, shift=lin.diag_abs())
    # the mirror-antisymmetric block (snapjump_cli.fe.stability.mirror) of a model of harmonics 0..2
    from snapjump_cli.fe.stability.mirror import MirrorOperator

    mh1 = MultiHarmonicModel(model, [0, 1, 2])
    MirrorOperator(mh1).matrix(np.zeros(mh1.n), 0.0)


def main(argv: list[str] | None = None, cpuinfo: str | Path = aot.CPUINFO) -> int:
    """``python -m snapjump_cli.fe.precompile [--if-stale]``: build the extension (with
    ``--if-stale`` only when its stamp does not match these kernel sources on this CPU). Exit 0
    also when it cannot be built (the JIT remains), with the reason on stderr; the stamp then
    records the failure, so that ``make install`` does not retry it until the sources or the CPU
    change."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m snapjump_cli.fe.precompile", description=main.__doc__.split("\n\n")[0])
    ap.add_argument("--if-stale", action="store_true", help="build only when the stamp does not match")
    ap.add_argument("--warm-followed", action="store_true",
                    help="instead, compile the followed branch's JIT kernels into numba's cache (warm_followed)")
    args = ap.parse_args(argv)
    if args.warm_followed:
        t0 = time.perf_counter()
        try:
            warm_followed()
        except Exception as exc:  # noqa: BLE001 - a cold cache only costs the first followed solve time
            sys.stderr.write(f"snapjump_cli.fe.precompile: followed kernels not warmed ({type(exc).__name__}: {exc})\n")
            return 0
        sys.stderr.write(f"snapjump_cli.fe.precompile: followed kernels compiled in {time.perf_counter() - t0:.0f} s\n")
        return 0
    why = aot.stale_reason(aot.read_stamp(), cpuinfo)
    if args.if_stale and not why:
        return 0
    # the signatures are those the dispatchers compile: this process must not use an existing build
    os.environ["SNAPJUMP_NO_AOT"] = "1"
    sys.stderr.write(f"snapjump_cli.fe.precompile: building the ahead-of-time kernels ({why or 'asked to'})\n")
    t0 = time.perf_counter()
    try:
        so = aot.build(collect_signatures(), cpuinfo)
    except Exception as exc:  # noqa: BLE001 - any failure leaves the JIT in place
        reason = f"{type(exc).__name__}: {exc}"
        aot.record_failure(reason, cpuinfo)
        sys.stderr.write(f"snapjump_cli.fe.precompile: not built ({reason}); the kernels run JIT-compiled\n")
        return 0
    sys.stderr.write(f"snapjump_cli.fe.precompile: built {so.name} in {time.perf_counter() - t0:.0f} s\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
