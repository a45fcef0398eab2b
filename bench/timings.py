"""Fixed costs: mesh generation, numba compilation (cold and warm cache), a warm ``snapjump curve``."""
from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

_WARM_SNIPPET = r"""
import json, time
t0 = time.perf_counter()
import snapjump_cli.fe.solve as s
t1 = time.perf_counter()
w = s.warm_up()
print(json.dumps({"import_s": t1 - t0, "warm_up_s": w}))
"""


def mesh_timings(cases, settings, repeats: int = 5) -> list[dict]:
    """Median wall time of :func:`snapjump_cli.mesh.build.mesh_scene` per (case, setting)."""
    from snapjump_cli.mesh.build import mesh_scene

    out = []
    for c in cases:
        for ms in settings:
            mesh_scene(c.scene, ms)  # first call: one-time imports
            ts, n = [], 0
            for _ in range(repeats):
                t0 = time.perf_counter()
                m = mesh_scene(c.scene, ms)
                ts.append(time.perf_counter() - t0)
                n = m.n_nodes
            out.append({"case": c.name, "order": ms.order, "nt": ms.nt, "aspect": ms.aspect, "n_nodes": n,
                        "median_s": statistics.median(ts), "min_s": min(ts)})
    return out


def _run_json(cmd: list[str], env: dict, timeout: float) -> tuple[dict | None, float, str]:
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout, cwd=REPO)
    except subprocess.TimeoutExpired:
        return None, time.perf_counter() - t0, f"timed out after {timeout:g} s"
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        return None, wall, (p.stderr.strip().splitlines() or ["?"])[-1]
    try:
        return json.loads(p.stdout.strip().splitlines()[-1]), wall, ""
    except (ValueError, IndexError):
        return None, wall, "unparsable output"


def numba_timings(timeout: float = 900.0) -> dict:
    """Compile every kernel in a fresh interpreter with an empty numba cache (``NUMBA_CACHE_DIR`` =
    a new temporary folder: cold), then again with that cache filled (warm)."""
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="snapjump-numba-") as d:
        env = dict(os.environ, NUMBA_CACHE_DIR=d)
        for label in ("cold", "warm"):
            res, wall, err = _run_json([sys.executable, "-c", _WARM_SNIPPET], env, timeout)
            out[label] = {"process_s": wall, **(res or {}), "error": err}
    return out


def curve_timing(design: str = "D", repeats: int = 2, timeout: float = 900.0) -> dict:
    """Wall time of ``snapjump curve --design D --format json`` as a subprocess (the default numba
    cache, already filled by the benchmark's own warm-up: a warm start)."""
    exe = Path(sys.executable).with_name("snapjump")
    cmd = [str(exe), "curve", "--design", design, "--format", "json"] if exe.exists() else \
        [sys.executable, "-m", "snapjump_cli", "curve", "--design", design, "--format", "json"]
    walls, solver_walls, err = [], [], ""
    for _ in range(repeats):
        res, wall, err = _run_json(cmd, dict(os.environ), timeout)
        if res is None:
            break
        walls.append(wall)
        solver_walls.append(res.get("wall_s"))
    return {"command": " ".join(["snapjump"] + cmd[1:] if exe.exists() else cmd), "walls_s": walls,
            "median_s": statistics.median(walls) if walls else None, "solver_wall_s": solver_walls, "error": err}
