"""``snapjump curve``: trace one scene's pressure-volume path and report its snap metrics.

JSON keys (stable): ``dE_J``, ``dE_norm`` (dE / (mu_i R_i^3)), ``dE_energy_J``, ``dE_path_J``,
``dy_pole_m``, ``dy_pole_norm`` (/R_i), ``p_star_Pa``, ``V_star_m3``, ``p_max_Pa``, ``h_imp_m``,
``L0_m``, ``snaps``, ``self_crossing``, ``lower_state_method``, ``n_steps``, ``n_newton``,
``wall_s``, ``mesh_sensitive``, ``mesh_check``, ``dE_J_coarse``, ``dy_pole_m_coarse``, the
harmonic check's ``asym_first``, ``asym_n``, ``asym_V_m3``, ``asym_p_Pa``, ``asym_lower_stable``
(null without ``--harmonics``), the followed branch's ``followed``, ``follow_n``, ``follow_N``,
``follow_kind``, ``follow_V_bif_m3``, ``follow_sec_n``, ``follow_sec_V_m3``, ``follow_sec_p_Pa`` and ``axisym_dE_J``,
``axisym_dy_pole_m``, ``axisym_h_imp_m``,
``axisym_V_star_m3``, ``axisym_p_star_Pa`` (null without ``--follow``: with it, ``dE_J``,
``dy_pole_m``, ``h_imp_m``, ``V_star_m3``, ``p_star_Pa`` describe the followed snap); with
``--imperfection DELTA`` the imperfect actuator's snap (docs/harmonics.md section 12) as
``imp_dE_J``, ``imp_dy_pole_m``, ``imp_h_imp_m``, ``imp_V_star_m3``, ``imp_p_star_Pa`` with
``imp_delta``, ``imp_n``, ``imp_N``, ``imp_shape``, ``imp_amplitude_m``, ``imp_note``; plus
diagnostics (``dE_rel_diff``, ``dy_pole_upper_m``, ``p_lower_Pa``, mesh size, ``max_dilatation``,
timings, ``stop_reason``; ``E_o_J`` for an outer cap alone).

With air (``--air-ml V0 [--gamma G] [--p0 P]``, docs/air.md) the snap metrics (``dE_J``,
``dy_pole_m``, ``h_imp_m``, ...) are the air snap's, and ``fluid``, ``air_V0_m3``, ``air_gamma``,
``air_p0_Pa``, ``V_disp_m3`` (the dispensed volume at the snap), ``p_before_Pa``, ``p_after_Pa``
(gauge), ``dV_snap_m3`` (the actuator's volume change; ``dV_snap_eq9_m3`` from eq 9),
``dE_rubber_J``, ``dE_gas_J``, ``water_dE_J``, ``water_dy_pole_m``, ``water_h_imp_m`` and the jump
heights ``y_jump_m``, ``water_y_jump_m`` (the jump model of ``rank``) are added; ``fluid`` is
``"water"`` and the other air keys null without it.

The jump (the mass-spring model of ``snapjump rank``, docs/physics.md section 6, on the reported
snap; a followed solve's followed snap): ``y_jump_m``, ``y_jump_norm`` (/R_i), ``jump_rise_m``,
``t_peak_s``, ``n_contacts``, ``jumped``, ``lift_off``, ``jump_complete``, ``jump_reason``, ``m_i_kg``,
``m_o_kg``, ``k_s`` (null without a snap or solid volumes; ``y_jump_m`` 0 without a snap) and, for a
followed solve, ``y_jump_axisym_m`` (the jump of the axisymmetric answer). Provenance:
``inputs`` (``scene``, ``mesh``, ``solver``, ``jump``: every input that made the answer),
``snapjump_version``, ``git_commit``, ``command``.

A scene is solved exactly as a sweep solves a design (:func:`snapjump_cli.fe.solve.solve_checked`):
a suspicious snap is re-solved on a finer mesh and the refined answer is reported, so ``curve``
and the ranked table give one answer per design and mesh.
"""
from __future__ import annotations

import json
import logging
import math
from pathlib import Path
from typing import Sequence

import click
import numpy as np

from snapjump_cli.cli import verbosity_options
from snapjump_cli.errors import BadInput
from snapjump_cli.settings import SolverSettings
from snapjump_cli.commands.options import (
    FiniteFloat,
    mesh_options,
    mesh_settings_from_options,
    pick_mesh_options,
    pick_scene_options,
    scene_from_options,
    scene_options,
)

__all__ = ["command", "main", "to_jsonable", "jump_keys", "JUMP_KEYS"]

log = logging.getLogger(__name__)

_SOLVER_DEFAULTS = SolverSettings()
#: The most sectors of a revolved export (--revolve): 0.5 degree; the export's size grows with it.
REVOLVE_MAX = 720


def to_jsonable(metrics: dict) -> dict:
    """Plain Python scalars (numpy scalars become floats/ints; NaN becomes None)."""
    out = {}
    for k, v in metrics.items():
        if isinstance(v, (np.floating, float)):
            v = float(v)
            v = v if math.isfinite(v) else None
        elif isinstance(v, (np.integer,)):
            v = int(v)
        elif isinstance(v, np.bool_):
            v = bool(v)
        out[k] = v
    return out


def _air_text(m: dict) -> list[str]:
    """The air snap's lines of the text report."""
    lines = [f"fluid            air: V0_sys {m['air_V0_m3'] * 1e6:.5g} ml at {m['air_p0_Pa']:.6g} Pa, gamma {m['air_gamma']:g}"]
    if m["snaps"]:
        lines += [
            f"air snap         p {m['p_before_Pa'] / 1e3:.5g} -> {m['p_after_Pa'] / 1e3:.5g} kPa (gauge) at the dispensed "
            f"volume {m['V_disp_m3'] * 1e6:.5g} ml",
            f"  actuator       {m['dV_snap_m3'] * 1e6:+.5g} ml   (eq 9: {m['dV_snap_eq9_m3'] * 1e6:+.5g} ml)",
            f"  dE = rubber + gas  {m['dE_rubber_J'] * 1e3:.6g} + {m['dE_gas_J'] * 1e3:.6g} mJ",
        ]
    if m.get("y_jump_m") is not None:
        lines.append(f"jump             {m['y_jump_m'] * 1e3:.5g} mm")
    if m.get("water_dE_J") is not None:
        w = f"water snap       dE {m['water_dE_J'] * 1e3:.6g} mJ"
        if m.get("water_dy_pole_m") is not None:
            w += f", dy_pole {m['water_dy_pole_m'] * 1e3:.5g} mm, h_imp {m['water_h_imp_m'] * 1e3:.5g} mm"
        if m.get("water_y_jump_m") is not None:
            w += f", jump {m['water_y_jump_m'] * 1e3:.5g} mm"
        lines.append(w)
    return lines


#: The jump keys of ``curve`` (those ``rank`` adds to a row, but ``rank``).
JUMP_KEYS: tuple[str, ...] = ("y_jump_m", "y_jump_norm", "jump_rise_m", "t_peak_s", "n_contacts", "jumped", "lift_off",
                              "jump_complete", "jump_reason", "m_i_kg", "m_o_kg", "k_s")


def jump_keys(m: dict, params, R_i: float | None) -> tuple[dict, object]:
    """The jump of the reported snap with the model ``rank`` applies to a row (:data:`JUMP_KEYS`;
    ``y_jump_axisym_m`` too for a followed solve) and its trajectory
    (:class:`snapjump_cli.jump.trajectory.JumpTrajectory`, ``None`` without one)."""
    from snapjump_cli import jump

    out: dict = {k: None for k in JUMP_KEYS}
    vi, vo = m.get("V_inner_solid_m3"), m.get("V_outer_solid_m3")
    if not (vi and vo):
        return out, None
    mi, mo = jump.masses(vi, vo, params.rho)
    out.update(m_i_kg=mi, m_o_kg=mo)
    if m.get("followed"):
        a = (m.get("axisym_dE_J"), m.get("axisym_dy_pole_m"), m.get("axisym_h_imp_m"))
        out["y_jump_axisym_m"] = (jump.jump_height(*a, mi, mo, params).y_jump_m
                                  if a[0] and a[0] > 0 and a[1] is not None and a[2] is not None else None)
    dE, dy, h = m.get("dE_J"), m.get("dy_pole_m"), m.get("h_imp_m")
    if not m.get("snaps") or not dE or dE <= 0 or dy is None or h is None:
        if not m.get("snaps"):  # as rank's no_snap row
            out.update(y_jump_m=0.0, jump_rise_m=0.0, t_peak_s=0.0, n_contacts=0, jumped=False, lift_off=False,
                       jump_complete=True, jump_reason="no snap", k_s=0.0, y_jump_norm=0.0)
        return out, None
    tr = jump.jump_trajectory(dE, dy, h, mi, mo, params, L0_m=m.get("L0_m"))
    jr = tr.result
    out.update(y_jump_m=float(jr.y_jump_m), jump_rise_m=float(jr.y_jump_m) - float(h), t_peak_s=float(jr.t_peak_s),
               n_contacts=int(jr.n_contacts), jumped=bool(jr.jumped), lift_off=bool(jr.lift_off),
               jump_complete=bool(jr.complete), jump_reason=str(jr.reason or ""), k_s=float(jr.k_s),
               y_jump_norm=float(jr.y_jump_m) / R_i if R_i else None)
    return out, tr


def _inputs(scene, ms, ss, params) -> dict:
    """The inputs of the answer (plain data): the scene's parameters, the mesh and solver settings
    and the jump model's parameters."""
    import dataclasses

    def plain(obj) -> dict:
        d = dataclasses.asdict(obj) if dataclasses.is_dataclass(obj) else dict(vars(obj))
        return {k: (v if isinstance(v, (str, int, float, bool, type(None))) else str(v)) for k, v in d.items()}

    sc = plain(scene)
    sc = {"kind": "design" if not hasattr(scene, "kind") else f"{scene.kind}_cap", **sc}
    return {"scene": sc, "mesh": plain(ms), "solver": plain(ss), "jump": plain(params)}


def _provenance() -> dict:
    from snapjump_cli import __version__
    from snapjump_cli.sweep.results import git_commit

    git = git_commit()
    import sys

    return {"snapjump_version": __version__,
            "git_commit": (git["commit"] + ("+dirty" if git.get("dirty") else "")) if git else None,
            "command": "snapjump " + " ".join(sys.argv[1:]) if sys.argv and "snapjump" in sys.argv[0] else None}


def _jumps(m: dict) -> dict:
    """``y_jump_m`` and ``water_y_jump_m`` (the jump model of ``rank``; ``None`` without a snap or
    solid volumes)."""
    from snapjump_cli import jump

    out = {"y_jump_m": None, "water_y_jump_m": None}
    vi, vo = m.get("V_inner_solid_m3"), m.get("V_outer_solid_m3")
    if not (vi and vo):
        return out
    mi, mo = jump.masses(vi, vo)
    for key, (dE, dy, h) in (("y_jump_m", (m["dE_J"], m["dy_pole_m"], m["h_imp_m"])),
                             ("water_y_jump_m", (m["water_dE_J"], m["water_dy_pole_m"], m["water_h_imp_m"]))):
        if dE and dy is not None and h is not None and dE > 0:
            out[key] = jump.jump_height(dE, dy, h, mi, mo).y_jump_m
    return out


def _jump_params(rho: float | None, c_d: float | None, alpha: float | None):
    """The jump model's parameters (``rank``'s defaults where not given), checked by the class."""
    from snapjump_cli.jump import JumpParams

    kw = {k: v for k, v in (("rho", rho), ("c_d", c_d), ("alpha", alpha)) if v is not None}
    try:
        return JumpParams(**kw)
    except (ValueError, TypeError) as e:
        raise BadInput(f"jump model: {e}") from None


def _fluid(air_ml: float | None, gamma: float | None, p0: float | None, harmonics: int):
    """The fluid of ``--air-ml / --gamma / --p0`` (``None``: water), checked by the settings class
    the YAML uses too."""
    from snapjump_cli.fe.axisym.fluid import FluidSettings, P0_DEFAULT
    from snapjump_cli.settings import SettingsError

    if air_ml is None:
        for name, v in (("--gamma", gamma), ("--p0", p0)):
            if v is not None:
                raise BadInput(f"{name} needs --air-ml (the gas's initial volume)")
        return None
    if harmonics:
        raise BadInput("--harmonics is not available with --air-ml")
    opts = {"V0_ml": "--air-ml", "gamma": "--gamma", "p0": "--p0", "kind": "--air-ml"}
    try:
        return FluidSettings(kind="air", V0_ml=air_ml, gamma=1.0 if gamma is None else gamma,
                             p0=P0_DEFAULT if p0 is None else p0)
    except SettingsError as e:
        raise BadInput(f"{opts[e.field]}: expected {e.expected}, got {e.value!r}") from None


#: The keys ``--imperfection`` adds (SI units).
IMP_KEYS: tuple[str, ...] = ("imp_delta", "imp_n", "imp_N", "imp_shape", "imp_amplitude_m", "imp_dE_J", "imp_dy_pole_m",
                             "imp_h_imp_m", "imp_V_star_m3", "imp_p_star_Pa", "imp_lower_state_method", "imp_note")


def _imperfect(res, scene, delta: float, n: int | None, N: int, time_limit_s: float):
    """Trace the imperfect actuator (:mod:`snapjump_cli.fe.branch.imperfection`) and add its keys to
    ``res.metrics``; returns its :class:`~snapjump_cli.fe.branch.imperfection.ImperfectResult` (``None`` when
    it was not traced to its snap)."""
    from snapjump_cli.fe.branch.imperfection import imperfection_shape, inner_thickness, trace_imperfect
    from snapjump_cli.fe.limits import TimeLimitExceeded, time_limit

    m = res.metrics
    if res.states is None or res.states.upper is None:
        raise click.ClickException("--imperfection: the perfect actuator does not snap; nothing to compare")
    if n is None:
        n = int(m["asym_n"]) if m.get("asym_first") else 1
    m.update({k: None for k in IMP_KEYS})
    m.update(imp_delta=float(delta), imp_n=n)
    try:
        with time_limit(time_limit_s):
            shape = imperfection_shape(res, n)
            r = trace_imperfect(res, shape, delta, inner_thickness(scene), N=N or None)
    except TimeLimitExceeded as exc:
        m["imp_note"] = f"not traced to its snap: {exc}"
        return None
    im = r.metrics
    m.update(imp_N=int(r.model.hn[-1]), imp_shape=shape.source, imp_amplitude_m=im["imp_amplitude_m"],
             imp_note=im["imp_note"] or None, imp_lower_state_method=im.get("lower_state_method"))
    for k in ("dE_J", "dy_pole_m", "h_imp_m", "V_star_m3", "p_star_Pa"):
        m["imp_" + k] = im.get(k)
    if im.get("dE_J") is None and not m["imp_note"]:
        m["imp_note"] = "the imperfect path did not reach a snap"
    return r if r.states.upper is not None else None



def _jump_text(m: dict) -> list[str]:
    """The jump's lines of the text report."""
    if m.get("y_jump_m") is None:
        return [f"jump             n/a ({m.get('jump_reason') or 'no snap metrics'})"]
    if not m["snaps"]:
        return ["jump             0 mm (no snap)"]
    flags = [("lifts off" if m["lift_off"] else "never leaves the ground"),
             ("jumped" if m["jumped"] else "did not jump")]
    if not m["jump_complete"]:
        flags.append("simulation incomplete")
    line = (f"jump             y_jump {m['y_jump_m'] * 1e3:.5g} mm (apex at {m['t_peak_s'] * 1e3:.4g} ms, "
            f"{m['n_contacts']} contact(s); {', '.join(flags)})")
    out = [line]
    if m.get("jump_reason"):
        out.append(f"  why            {m['jump_reason']}")
    if m.get("y_jump_axisym_m") is not None:
        out.append(f"  axisymmetric   {m['y_jump_axisym_m'] * 1e3:.5g} mm with the axisymmetric snap (does not happen)")
    return out


def _text(scene, m: dict) -> str:
    name = getattr(scene, "name", None) or type(scene).__name__
    lines = [f"scene            {name}"]
    if not m["snaps"]:
        lines.append("snaps            no (no limit point in volume before the trace bound)")
    else:
        lines += [
            f"dE               {m['dE_J'] * 1e3:.6g} mJ   (dE/(mu_i R_i^3) = {m['dE_norm']:.5g})",
            f"  energy / path  {m['dE_energy_J'] * 1e3:.6g} / "
            + (f"{m['dE_path_J'] * 1e3:.6g} mJ  (rel. diff {m['dE_rel_diff']:.1e})" if m.get("dE_path_J") is not None else "n/a (descent)"),
            f"dy_pole          {m['dy_pole_m'] * 1e3:.5g} mm   (dy/R_i = {m['dy_pole_norm']:.5g})",
            f"p* / V*          {m['p_star_Pa'] / 1e3:.5g} kPa / {m['V_star_m3'] * 1e6:.5g} ml",
            f"lower state      {m['lower_state_method']}",
        ]
        if m.get("h_imp_m") is not None:
            lines.append(f"h_imp            {m['h_imp_m'] * 1e3:.5g} mm")
        if m.get("L0_m") is not None:
            lines.append(f"L_0              {m['L0_m'] * 1e3:.5g} mm")
    if m.get("mesh_check"):
        lines.append(f"mesh check       {m['mesh_check']}"
                     + (f" (coarse: dE {m['dE_J_coarse'] * 1e3:.6g} mJ, dy_pole {m['dy_pole_m_coarse'] * 1e3:.5g} mm)"
                        if m.get("dE_J_coarse") is not None else ""))
    if m.get("mesh_sensitive"):
        lines.append("warning          mesh_sensitive: this snap changes with the mesh (see the mesh check); "
                     "compare finer meshes (--nt, --aspect)")
    if m.get("fluid") == "air":
        lines += _air_text(m)
    if m.get("E_o_J") is not None:
        lines.append(f"E_o (p/mu_o=0.5) {m['E_o_J'] * 1e3:.6g} mJ")
    if m.get("asym_first") is not None:
        if m["asym_first"]:
            lines.append(f"asymmetric mode  n = {m['asym_n']} loses stability before V*, at "
                         f"V = {m['asym_V_m3'] * 1e6:.5g} ml, p = {m['asym_p_Pa'] / 1e3:.5g} kPa: the axisymmetric "
                         "snap is not what happens" + ("" if m.get("followed") else " (--follow traces what does)"))
        else:
            lines.append("asymmetric mode  none up to V* (harmonics checked)")
        if m.get("followed"):
            sec = m.get("follow_sec_n") is not None
            kind = "" if sec else f"{m['follow_kind']}, "  # (after a secondary: that branch's kind, below)
            lines.append(f"followed branch  n = {m['follow_n']} ({kind}harmonics up to {m['follow_N']}) "
                         f"from V = {m['follow_V_bif_m3'] * 1e6:.5g} ml: the snap above is the followed one; "
                         f"axisymmetric dE {m['axisym_dE_J'] * 1e3:.6g} mJ, dy_pole {m['axisym_dy_pole_m'] * 1e3:.5g} mm, "
                         f"V* {m['axisym_V_star_m3'] * 1e6:.5g} ml")
            if sec and m.get("follow_kind") == "jump":
                lines.append(f"secondary        the branch of n = {m['follow_n']} folds at V* and the state it jumps "
                             f"to there is unstable in n = {m['follow_sec_n']}: the jump goes on at that volume to "
                             "the state above (every harmonic kept, energy descent)")
            elif sec:
                lines.append(f"secondary        the branch of n = {m['follow_n']} loses stability to n = "
                             f"{m['follow_sec_n']} at V = {m['follow_sec_V_m3'] * 1e6:.5g} ml, before its own snap: "
                             f"the snap above is that of the branch leaving it there ({m['follow_kind']}, every "
                             "harmonic kept)")
        elif m.get("followed") is False and m.get("follow_note"):
            lines.append(f"followed branch  not followed: {m['follow_note']}")
        if m.get("asym_lower_stable") is not None:
            lines.append(f"lower state, 3D {'stable' if m['asym_lower_stable'] else 'UNSTABLE'} against the harmonics checked"
                         + (" (the axisymmetric path's)" if m.get("followed") else ""))
    if m.get("imp_delta") is not None:
        if m.get("imp_dE_J") is not None:
            lines.append(f"imperfect        n = {m['imp_n']} ({m['imp_shape']} mode), amplitude {m['imp_delta']:g} t_i "
                         f"({m['imp_amplitude_m'] * 1e6:.4g} um): snaps at V* {m['imp_V_star_m3'] * 1e6:.5g} ml, "
                         f"p* {m['imp_p_star_Pa'] / 1e3:.5g} kPa, dE {m['imp_dE_J'] * 1e3:.6g} mJ, "
                         f"dy_pole {m['imp_dy_pole_m'] * 1e3:.5g} mm")
        else:
            lines.append(f"imperfect        n = {m['imp_n']}, amplitude {m['imp_delta']:g} t_i: {m['imp_note']}")
    if m.get("fluid") != "air" and m.get("m_i_kg") is not None:
        lines += _jump_text(m)
    lines += [
        f"p_max            {m['p_max_Pa'] / 1e3:.5g} kPa",
        f"self-crossing    {'yes' if m['self_crossing'] else 'no'}",
        f"solver           {m['n_steps']} steps, {m['n_newton']} Newton iterations, {m['n_dofs']} dofs, {m['wall_s']:.3g} s",
    ]
    return "\n".join(lines)


@click.command("curve", context_settings={"help_option_names": ["-h", "--help"]})
@scene_options
@mesh_options
@click.option("--full", is_flag=True, help="Trace the whole curve (to 1.5 p_c or the volume bound) instead of stopping once the snap is characterised.")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True, help="Output format.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the traced path to this CSV file, one row per step: p_Pa, V_m3, y_pole_m, strain_energy_J, "
                   "arc_length, step, state (start, p_max, upper, lower or empty), on_path.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Draw the p-V curve (kPa against ml, dE shaded; a followed solve's followed snap as the main "
                   "curve) to this .png, .svg or .pdf file.")
@click.option("--shapes", "shapes_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Draw the undeformed state, the pressure maximum, the upper and the lower state (sections "
                   "mirrored about the axis, one scale, coloured by the largest principal stretch; a followed solve: "
                   "the states the actuator takes, two sections each, the stretch of the 3D deformation gradient) "
                   "to this .png, .svg or .pdf file.")
@click.option("--animation", "animation_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the section moving along the path the actuator takes (stable states, the snap at "
                   "fixed volume as a jump, the lower state), beside its point on the p-V curve, to this GIF file.")
@click.option("--export", "export_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the traced path as a ParaView time series (FILE.pvd with the folder FILE_steps/, or "
                   "FILE.xdmf) in mm, z up, ground at z = 0 (the frame of the STEP/STL solids): displacement_mm, "
                   "max_principal_stretch, rubber_mean_stress_Pa; each step's p, V and state. A followed solve: "
                   "the states the actuator takes, in 3D.")
@click.option("--revolve", type=click.IntRange(min=0, max=REVOLVE_MAX), default=0, show_default=True, metavar="N",
              help="With --export: the solid of revolution in N sectors (3 <= N <= 720) instead of the section "
                   "(a followed solve's states are always revolved: 48 sectors unless N is given).")
@click.option("--jump", "jump_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Draw the jump of the mass-spring model (both masses' heights against time, lift-off and "
                   "apex marked) to this .png, .svg or .pdf file.")
@click.option("--normalised", is_flag=True,
              help="Draw --plot on the paper's normalised axes (p/mu_i against dV/R_i^3) instead of kPa and ml.")
@click.option("--rho", type=FiniteFloat(), default=None, help="Jump model: rubber density [kg/m^3] (rank's default).")
@click.option("--c-d", "c_d", type=FiniteFloat(), default=None, help="Jump model: dashpot coefficient [kg/s] (rank's default).")
@click.option("--alpha", type=FiniteFloat(), default=None, help="Jump model: ground restitution coefficient, in [0, 1] (rank's default).")
@click.option("--overwrite", is_flag=True,
              help="Replace existing --csv / --plot / --shapes / --animation / --export files (refused by default).")
@click.option("--time-limit", "time_limit_s", type=click.FloatRange(min=0, min_open=True, max=1e9),
              default=_SOLVER_DEFAULTS.time_limit_s, show_default=True, metavar="SECONDS",
              help="CPU seconds the solve may take (the mesh check's re-solve included); beyond them it stops "
                   "with an error saying so.")
@click.option("--max-nodes", type=click.IntRange(10, 10_000_000), default=_SOLVER_DEFAULTS.max_nodes,
              show_default=True, metavar="N", help="Refuse to solve a mesh of more than N nodes.")
@click.option("--harmonics", type=click.IntRange(0, 64), default=0, show_default=True, metavar="N",
              help="Check every path state up to the snap and the lower state against non-axisymmetric "
                   "modes cos(n phi), n = 1..N (Fourier-harmonic tangents; 0 = off). Reports asym_first, "
                   "asym_n, asym_V_m3, asym_p_Pa and asym_lower_stable.")
@click.option("--follow", is_flag=True,
              help="With --harmonics: when a harmonic loses stability before V*, trace the branch that "
                   "bifurcates there (nonlinear Fourier series of that harmonic and its multiples) to its own "
                   "snap, and report that snap as the answer (the axisymmetric one as axisym_*).")
@click.option("--margins", is_flag=True,
              help="With --harmonics: the smallest eigenvalue of every harmonic's tangent n = 0..N (in mu_i/R_i^2) "
                   "along the path: asym_margin, asym_margin_n, asym_margin_V_m3, and margin_n0.. columns in --csv.")
@click.option("--follow-N", "follow_N", type=click.IntRange(0, 16), default=0, show_default=True, metavar="N",
              help="Highest harmonic of the followed branch (0: 4 n_c for the critical harmonic n_c).")
@click.option("--follow-full", "follow_full", is_flag=True,
              help="With --follow: the reference mode, every branch traced to its snap and its lower state "
                   "searched (slower; the default traces only what the actuator passes through and lands a "
                   "subcritical n = 1 snap on the axisymmetric path's inverted state where that is stable).")
@click.option("--imperfection", "imperfection", type=click.FloatRange(min=0.0, max=1.0), default=None,
              metavar="DELTA",
              help="Also trace the actuator with an initial geometric imperfection: the lowest mode of harmonic "
                   "--imperfection-n (the critical mode if it goes unstable before V*, else its least stable one) "
                   "with a largest displacement of DELTA times the inner cap's thickness; reports imp_* keys.")
@click.option("--imperfection-n", "imperfection_n", type=click.IntRange(1, 16), default=None, metavar="N",
              help="Harmonic of --imperfection (default: the first unstable harmonic of --harmonics, else 1).")
@click.option("--air-ml", "air_ml", type=FiniteFloat(), default=None, metavar="V0",
              help="Inflate with air from a syringe: the gas volume of syringe, tube and cavity before inflation "
                   "[mL] (paper S3's V0_sys). The snap is then at the limit of the dispensed volume; the water "
                   "answers are reported beside it.")
@click.option("--gamma", "gamma", type=FiniteFloat(), default=None,
              help="With --air-ml: the gas's polytropic exponent, 1 (isothermal, default) to 5/3; 1.4: adiabatic air.")
@click.option("--p0", "p0", type=FiniteFloat(), default=None, metavar="PA",
              help="With --air-ml: the gas's initial absolute pressure [Pa] (default 101325).")
@verbosity_options
def command(fmt: str, csv_path: Path | None, plot_path: Path | None, full: bool, overwrite: bool, harmonics: int,
            shapes_path: Path | None, animation_path: Path | None, export_path: Path | None, revolve: int,
            air_ml: float | None, gamma: float | None, p0: float | None, follow: bool, follow_N: int, follow_full: bool, margins: bool,
            time_limit_s: float, max_nodes: int, imperfection: float | None, imperfection_n: int | None,
            jump_path: Path | None, normalised: bool, rho: float | None, c_d: float | None, alpha: float | None,
            **kw) -> None:
    """Trace one scene's pressure-volume path through its limit points and report the snap.

    \b
    Examples:
      snapjump curve --design D --plot d.png
      snapjump curve --design D --jump d_jump.png --format json
      snapjump curve --cap --theta 60 --eta 30 --bc clamped --format json
      snapjump curve --design C --plot c.png --csv c.csv
      snapjump curve --design D --shapes d.png --animation d.gif --export d.pvd
      snapjump curve --cap outer --theta 90 --eta 16.5
      snapjump curve --design B --harmonics 4 --follow --plot b.png
      snapjump curve --design D --harmonics 4 --imperfection 0.01
      snapjump curve --design C --air-ml 45 --plot c_air.png
    """
    from snapjump_cli.fe.solve import SolveFailed, solve_checked

    if follow and harmonics < 1:
        raise BadInput("--follow needs --harmonics N with N >= 1 (the check that finds the bifurcation)")
    if margins and harmonics < 1:
        raise BadInput("--margins needs --harmonics N with N >= 1 (the harmonics whose margins are reported)")
    if imperfection_n is not None and imperfection is None:
        raise BadInput("--imperfection-n needs --imperfection DELTA (the amplitude)")
    scene = scene_from_options(**pick_scene_options(kw))
    ms = mesh_settings_from_options(**pick_mesh_options(kw))
    fluid = _fluid(air_ml, gamma, p0, harmonics)
    if imperfection is not None and fluid is not None:
        raise BadInput("--imperfection is not available with --air-ml")
    from snapjump_cli.viz.outputs import check_outputs, write_outputs

    params = _jump_params(rho, c_d, alpha)
    outputs = {"--csv": csv_path, "--plot": plot_path, "--shapes": shapes_path, "--animation": animation_path,
               "--export": export_path, "--jump": jump_path}
    check_outputs(outputs, revolve, overwrite)
    ss = SolverSettings(full=full, harmonics=harmonics, follow=follow, follow_N=follow_N,
                        follow_mode="full" if follow_full else "actuator", margins=margins,
                        time_limit_s=time_limit_s, max_nodes=max_nodes)
    try:
        res = solve_checked(scene, ms, ss, fluid=fluid)
    except SolveFailed as exc:
        raise click.ClickException(f"solve failed: {exc}") from None
    imperfect = None
    if imperfection is not None:
        imperfect = _imperfect(res, scene, imperfection, imperfection_n, follow_N, time_limit_s)
    m = to_jsonable(res.metrics)
    if fluid is not None:
        m.update(_jumps(m))
    jk, trajectory = jump_keys(m, params, getattr(scene, "R_i", None) or getattr(scene, "R", None))
    m.update(jk)
    if jump_path is not None and trajectory is None:
        raise click.ClickException(f"--jump {jump_path}: no jump to draw ({m.get('jump_reason') or 'no solid volumes'})")
    m = to_jsonable(m)
    m["inputs"] = _inputs(scene, ms, ss, params)
    m.update(_provenance())
    write_outputs(res, scene, m, outputs, revolve, normalised=normalised, jump_trajectory=trajectory,
                  imperfect=imperfect)
    if fmt == "json":
        click.echo(json.dumps(m, sort_keys=False))
    else:
        click.echo(_text(scene, m))


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump curve`` with ``argv``; returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["curve", *(argv or [])])
