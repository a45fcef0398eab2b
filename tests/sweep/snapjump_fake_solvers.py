"""TEST-ONLY fake solvers for the sweep tests (never used by the package itself).

They return every key of ``RESULT_KEYS`` with cheap, deterministic, plausible values, so that the
sweep machinery (resume, chunking, failure handling, schema) can be tested without the FE solver.
Used in-process (``run_sweep(..., solve_fn=fast_solve)``, ``cli.main(argv, solve_fn=fast_solve)``)
and in subprocesses through ``fake_sweep_main.py`` (the real CLI with ``slow_solve`` injected).

Environment knobs (subprocess tests):
``SNAPJUMP_FAKE_DELAY``  seconds each ``slow_solve`` call sleeps (default 0.2);
``SNAPJUMP_FAKE_LOG``    file to which every call appends ``<theta_o> <eta_o> <mu_ratio>`` + pid.
"""
from __future__ import annotations

import math
import os
import time

from snapjump_cli.geometry.caps import design_volumes
from snapjump_cli.sweep.rows import AIR_KEYS, FOLLOW_ROW_KEYS, RESULT_KEYS

WARM_UPS = []


class SolveFailed(RuntimeError):
    """Stand-in for snapjump_cli.fe.solve.SolveFailed."""


def warm_up() -> None:
    WARM_UPS.append(os.getpid())


def _log_call(design) -> None:
    path = os.environ.get("SNAPJUMP_FAKE_LOG")
    if path:
        line = f"{design.eta_i!r} {design.theta_i_deg!r} {design.eta_o!r} {design.theta_o_deg!r} {design.mu_ratio!r} {os.getpid()}\n"
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line.encode())
        finally:
            os.close(fd)


def fast_solve(design, mesh, solver) -> dict:
    """A snap for mu_ratio > 2 or theta_o >= 85, no snap otherwise."""
    _log_call(design)
    vol = design_volumes(design)
    snaps = design.mu_ratio > 2 or design.theta_o_deg >= 85
    dE = (1e-3 * design.mu_ratio * design.eta_o / design.eta_i) if snaps else 0.0
    dy = (0.004 * design.mu_ratio ** 0.5 * design.theta_o_deg / 80.0) if snaps else float("nan")
    out = {k: 0.0 for k in RESULT_KEYS}
    out.update(mesh_sensitive=False, mesh_check="", dE_J_coarse=None, dy_pole_m_coarse=None, asym_first=None,
               asym_n=None, asym_V_m3=None, asym_p_Pa=None, asym_lower_stable=None)
    out.update({k: None for k in FOLLOW_ROW_KEYS})
    out.update({k: None for k in AIR_KEYS}, fluid="water")
    out.update(
        dE_J=dE, dE_norm=dE / (design.mu_i * design.R_i ** 3), dE_energy_J=dE, dE_path_J=dE * (1 + 1e-6),
        dE_rel_diff=1e-6, dy_pole_m=dy, dy_pole_upper_m=dy, dy_pole_norm=dy / design.R_i,
        p_star_Pa=1e4, V_star_m3=1e-5, p_max_Pa=1.2e4, h_imp_m=0.2 * design.R_i, L0_m=0.5 * design.R_i,
        snaps=snaps, self_crossing=False, lower_state_method="path", n_steps=40, n_newton=120, wall_s=0.01,
        n_nodes=10 * mesh.nt * (mesh.order + 1), n_elements=5 * mesh.nt, n_dofs=20 * mesh.nt,
        V_inner_solid_m3=vol["inner_solid"], V_outer_solid_m3=vol["outer_solid"],
    )
    if not snaps:
        out.update(dy_pole_upper_m=float("nan"), dy_pole_norm=float("nan"), lower_state_method="none")
    return out


def flaky_solve(design, mesh, solver) -> dict:
    """fast_solve, but: theta_o == 86 raises SolveFailed; theta_o == 88 returns a NaN metric in a
    snapping result; theta_o == 84 returns inf in h_imp_m; eta_o == 7 lacks a key; eta_o == 9 has None for a metric of a snap."""
    if design.theta_o_deg == 86:
        raise SolveFailed("continuation stalled at step 17 (ds below ds_min)")
    out = fast_solve(design, mesh, solver)
    if design.theta_o_deg == 88:
        out.update(snaps=True, dE_J=float("nan"))
    if design.theta_o_deg == 84:
        out.update(snaps=True, h_imp_m=float("inf"))
    if design.eta_o == 7:
        out.pop("L0_m")
    if design.eta_o == 9:
        out.update(snaps=True, dy_pole_upper_m=None)
    return out


_CALLS = []


def slow_solve(design, mesh, solver) -> dict:
    """fast_solve after sleeping SNAPJUMP_FAKE_DELAY seconds. With SNAPJUMP_FAKE_BLOCK_AFTER=n, every
    call after the n-th of this process blocks (until the process is stopped), so a test can stop a
    sweep mid-run whatever the machine's load: the run can never finish before it is stopped."""
    _CALLS.append(1)
    block = int(os.environ.get("SNAPJUMP_FAKE_BLOCK_AFTER", "0") or 0)
    if block and len(_CALLS) > block:
        while True:
            time.sleep(0.05)
    time.sleep(float(os.environ.get("SNAPJUMP_FAKE_DELAY", "0.2")))
    return fast_solve(design, mesh, solver)


def crash_solve(design, mesh, solver) -> dict:
    """Kills its worker process outright for theta_o == 85 (like a segfault in a kernel)."""
    if design.theta_o_deg == 85:
        os._exit(17)
    time.sleep(0.05)
    return fast_solve(design, mesh, solver)


def thread_env(design, mesh, solver) -> dict:
    """fast_solve, reporting the worker's thread-cap variables in lower_state_method."""
    out = fast_solve(design, mesh, solver)
    out["lower_state_method"] = ",".join(
        f"{v}={os.environ.get(v)}" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")
    )
    return out


def is_finite(x) -> bool:
    return x is not None and math.isfinite(x)


INTERRUPT_AFTER = [10**9]
_N_CALLS = [0]


def interrupting_solve(design, mesh, solver) -> dict:
    """fast_solve, but the INTERRUPT_AFTER[0]-th call raises KeyboardInterrupt (like Ctrl-C)."""
    _N_CALLS[0] += 1
    if _N_CALLS[0] >= INTERRUPT_AFTER[0]:
        _N_CALLS[0] = 0
        _log_call(design)
        raise KeyboardInterrupt
    return fast_solve(design, mesh, solver)


def broken_if_called(design, mesh, solver) -> dict:
    raise AssertionError("the solver must not be called")
