"""One timed solve of one scene at one mesh setting, in a forked child with a hard time limit.

The parent has already compiled the numba kernels (``warm_up()``); a ``fork`` child inherits them,
so every timing is warm. The child solves the scene, and, when the first solve was cheap, repeats
it (``repeats_for``) so that the reported wall time is a median; the repeats also tell whether two
identical runs give bitwise-identical metrics. If the first solve does not finish within
``timeout`` seconds, the child is killed and the run is recorded as ``timeout``.
"""
from __future__ import annotations

import math
import multiprocessing as mp
import os
import statistics
import time
import traceback
from typing import Any

#: Metric keys kept per run (the rest of ``SceneResult.metrics`` is not needed by the report).
KEEP = ("dE_J", "dE_norm", "dE_energy_J", "dE_path_J", "dE_rel_diff", "dy_pole_m", "dy_pole_norm",
        "p_star_Pa", "V_star_m3", "h_imp_m", "snaps", "self_crossing", "lower_state_method", "n_steps",
        "n_newton", "n_rejected", "n_dofs", "n_elements", "wall_s", "mesh_s", "t_assembly_s", "t_factor_s",
        "stop_reason", "max_dilatation")
#: Metrics compared bitwise between repeats.
DETERMINISM_KEYS = ("dE_J", "dy_pole_m", "p_star_Pa", "V_star_m3", "n_steps", "n_newton", "lower_state_method")


def repeats_for(wall_s: float, max_repeats: int = 5) -> int:
    """How many solves in total for a run whose first solve took ``wall_s``: 5 below 1 s, 3 below
    5 s, else 1 (bounded by ``max_repeats``)."""
    n = 5 if wall_s < 1.0 else 3 if wall_s < 5.0 else 1
    return max(1, min(n, max_repeats))


def _plain(v: Any) -> Any:
    try:
        import numpy as np

        if isinstance(v, np.generic):
            v = v.item()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _child(conn, scene, mesh, solver, max_repeats: int) -> None:
    from snapjump_cli.fe.solve import SolveFailed, solve_scene

    try:
        n = 1
        k = 0
        while k < n:
            t0 = time.perf_counter()
            try:
                m = solve_scene(scene, mesh, solver).metrics
                msg = {"status": "ok" if m.get("snaps") else "no_snap",
                       "metrics": {key: _plain(m.get(key)) for key in KEEP}}
            except SolveFailed as e:
                msg = {"status": "failed", "error": f"SolveFailed: {e}"}
            msg["t"] = time.perf_counter() - t0
            conn.send(msg)
            if k == 0:
                n = repeats_for(msg["t"], max_repeats) if msg["status"] != "failed" else 1
            k += 1
    except BaseException as e:  # noqa: BLE001 - report any crash of the solver to the parent
        conn.send({"status": "error", "error": f"{type(e).__name__}: {e}", "traceback": traceback.format_exc(),
                   "t": float("nan")})
    finally:
        conn.send(None)
        conn.close()


def run_one(scene, mesh, solver, timeout: float, max_repeats: int = 5) -> dict:
    """Solve ``scene`` in a forked child; returns a record (see the module docstring).

    Keys: ``status`` (ok | no_snap | failed | error | timeout), ``error``, ``metrics`` (of the
    first solve), ``walls`` (every solve's wall time, s), ``wall_s`` (median), ``repeat_identical``
    (None with a single solve).
    """
    ctx = mp.get_context("fork")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(child, scene, mesh, solver, max_repeats), daemon=True)
    proc.start()
    child.close()
    msgs: list[dict] = []
    status = None
    deadline = time.monotonic() + timeout
    try:
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not parent.poll(remaining):
                status = "timeout"
                break
            try:
                msg = parent.recv()
            except EOFError:
                status = "error"
                msgs.append({"status": "error", "error": f"child process died (exit code {proc.exitcode})"})
                break
            if msg is None:
                break
            msgs.append(msg)
            if len(msgs) == 1:  # repeats are cheap by construction: allow them time of their own
                deadline = time.monotonic() + max(timeout, 10 * msg.get("t", 0.0) * max_repeats)
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(5)
        parent.close()
    if status == "timeout" and not msgs:
        return {"status": "timeout", "error": f"no result within {timeout:g} s", "metrics": {}, "walls": [],
                "wall_s": None, "repeat_identical": None}
    first = msgs[0]
    walls = [m["t"] for m in msgs if m.get("status") == first["status"]]
    rec = {"status": first["status"], "error": first.get("error", ""), "metrics": first.get("metrics", {}),
           "walls": walls, "wall_s": statistics.median(walls) if walls else None, "repeat_identical": None}
    if "traceback" in first:
        rec["traceback"] = first["traceback"]
    if len(msgs) > 1:
        ref = {k: first.get("metrics", {}).get(k) for k in DETERMINISM_KEYS}
        rec["repeat_identical"] = all(
            m.get("status") == first["status"] and {k: m.get("metrics", {}).get(k) for k in DETERMINISM_KEYS} == ref
            for m in msgs[1:])
    return rec


def cpu_info(cpuinfo: str = "/proc/cpuinfo") -> dict:
    """CPU model and core count (``cpuinfo``: the model name, family/model numbers, clock and
    widest vector extension, since the name alone may not tell two machines apart), load average
    and Python/numba versions."""
    import platform

    from snapjump_kernels.aot import cpu_fields

    fields = cpu_fields(cpuinfo)
    model = fields.get("model name", "?")
    flags = set(fields.get("flags", "").split())
    vec = next((v for v in ("avx512f", "avx2", "avx", "sse4_2") if v in flags), "")
    info = {"cpu_model": model, "cores": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform()}
    if fields:
        info["cpu_id"] = (f"family {fields.get('cpu family', '?')} model {fields.get('model', '?')}, "
                          f"{float(fields.get('cpu MHz', 'nan')):.0f} MHz" + (f", {vec}" if vec else ""))
    try:
        info["loadavg"] = os.getloadavg()
    except OSError:
        pass
    try:
        import numba
        import numpy

        info.update(numba=numba.__version__, numpy=numpy.__version__)
    except ImportError:  # pragma: no cover
        pass
    try:
        with open("/proc/meminfo") as fh:
            info["mem_total"] = fh.readline().split(":", 1)[1].strip()
    except OSError:
        pass
    return info
