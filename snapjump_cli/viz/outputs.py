"""The files ``snapjump curve`` writes for one solved scene, all at once: ``--csv`` (the steps; a
followed solve's branch after them, column ``branch``), ``--plot`` (the p-V curve), ``--shapes``,
``--animation`` (the path the actuator takes), ``--export`` (``--revolve``; a followed solve's
states in 3D) and ``--jump`` (the mass-spring trajectory).

:func:`check_outputs` refuses bad places before anything is solved (exit code 2, one line);
:func:`write_outputs` renders every file into a temporary name beside its target and renames them
only when all are complete (:class:`snapjump_cli.files.AtomicFiles`), so a failure leaves the old
files (or none) in place.
"""
from __future__ import annotations

import csv
import logging
from pathlib import Path
from typing import Callable

import numpy as np

from snapjump_cli.errors import BadInput

__all__ = ["OUTPUT_SUFFIXES", "check_outputs", "write_outputs", "scene_title", "imperfect_curve"]

log = logging.getLogger(__name__)

#: The file suffixes of each output option.
OUTPUT_SUFFIXES = {"--csv": (".csv",), "--plot": (".png", ".svg", ".pdf"), "--shapes": (".png", ".svg", ".pdf"),
                   "--animation": (".gif",), "--export": (".pvd", ".xdmf"), "--jump": (".png", ".svg", ".pdf")}
_NEEDS = {"--plot": "matplotlib", "--shapes": "matplotlib", "--animation": "matplotlib", "--export": "meshio",
          "--jump": "matplotlib"}
_EXTRA = {"matplotlib": "pip install 'snapjump[plots]'", "meshio": "pip install meshio"}


def check_outputs(paths: dict[str, Path | None], revolve: int, overwrite: bool) -> None:
    """Raise :class:`BadInput` (one line) for an unusable output: a wrong suffix, a missing folder,
    an existing file without ``overwrite``, ``--revolve`` without ``--export`` or below 3 sectors, a
    missing optional package. ``paths`` maps the option (``"--shapes"``, ...) to its path or None."""
    from snapjump_cli.files import check_writable

    for opt, p in paths.items():
        if p is None:
            continue
        if p.suffix.lower() not in OUTPUT_SUFFIXES[opt]:
            raise BadInput(f"{opt} {p}: expected a {' or '.join(OUTPUT_SUFFIXES[opt])} file")
        if not p.parent.exists():
            raise BadInput(f"{opt} {p}: directory {p.parent} does not exist")
        check_writable(p, BadInput, overwrite=overwrite)
        if opt == "--export" and p.suffix.lower() == ".pvd":
            from snapjump_cli.viz.export import steps_folder

            folder = steps_folder(p)
            if folder.exists() and not overwrite:
                raise BadInput(f"--export {p}: its step folder {folder} exists; pass --overwrite to replace it")
            if folder.exists() and not folder.is_dir():
                raise BadInput(f"--export {p}: {folder} is a file, not the step folder")
        if opt in _NEEDS:
            _require(_NEEDS[opt], opt)
    if revolve and paths.get("--export") is None:
        raise BadInput("--revolve needs --export FILE.pvd|FILE.xdmf")
    if revolve and revolve < 3:
        raise BadInput(f"--revolve: expected 0 (the section) or at least 3 sectors, got {revolve}")


def _require(module: str, opt: str) -> None:
    import importlib

    try:
        importlib.import_module(module)
    except ImportError:
        raise BadInput(f"{opt} needs {module}, which is not installed ({_EXTRA[module]})") from None


def _write_csv(columns: dict[str, list], path: Path) -> None:
    names = list(columns)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in zip(*columns.values()):
            w.writerow([_cell(x) for x in row])


def _cell(x) -> str:
    if isinstance(x, str):
        return x
    if isinstance(x, (bool, int)) or (hasattr(x, "dtype") and x.dtype.kind in "iub"):
        return str(int(x))
    x = float(x)
    return "" if x != x else f"{x:.12g}"


def imperfect_curve(r) -> dict:
    """The imperfect actuator's path in SI units for the p-V plot: ``V_m3``, ``p_Pa`` and, with a
    snap, ``snap_V_m3`` / ``snap_p_Pa``, ``delta``, ``n``."""
    from snapjump_cli.fe.axisym.metrics import snap_sequence

    mh, sc = r.model, r.tracer.sc
    L3, S = mh.L**3, mh.S
    out = {"V_m3": np.array([pt.zeta[0] * sc[0] for pt in r.path.points]) * L3,
           "p_Pa": np.array([pt.p for pt in r.path.points]) * S, "delta": r.delta, "n": int(r.shape.n)}
    if r.states.upper is not None and r.states.lower is not None:
        seq = snap_sequence(r.path, r.states)
        out["snap_V_m3"] = np.array([pt.zeta[0] * sc[0] for pt in seq]) * L3
        out["snap_p_Pa"] = np.array([pt.p for pt in seq]) * S
    return out


def scene_title(scene) -> str:
    """The figures' title of a scene: ``design D``, ``design (8.5, 60, 16.5, 90, 5.8)`` or
    ``inner cap, theta 60 deg, eta 8.5``."""
    from snapjump_cli.geometry.caps import CapScene

    title = getattr(scene, "name", None) or ""
    if isinstance(scene, CapScene):
        return title or f"{scene.kind} cap, theta {scene.theta_deg:g} deg, eta {scene.eta:g}"
    if not title:
        return (f"design ({scene.eta_i:g}, {scene.theta_i_deg:g}, {scene.eta_o:g}, {scene.theta_o_deg:g}, "
                f"{scene.mu_ratio:g})")
    return f"design {title}"


def write_outputs(res, scene, metrics: dict, paths: dict[str, Path | None], revolve: int = 0, *,
                  normalised: bool = False, jump_trajectory=None, imperfect=None) -> list[Path]:
    """Write every requested output of a solved scene, all or none (module docstring).

    Parameters
    ----------
    res : the :class:`~snapjump_cli.fe.solve.SceneResult`
    scene : its scene (the title, and ``ΔV`` for a single cap's supplied volume)
    metrics : the reported metrics (JSON-ready), for the p-V plot
    paths : option -> path (``--csv``, ``--plot``, ``--shapes``, ``--animation``, ``--export``)
    revolve : sectors of the exported solid of revolution (0: the section; a followed solve's
        states are always revolved, in :data:`FOLLOWED_SECTORS` sectors by default)
    normalised : the p-V plot on the paper's normalised axes instead of kPa and ml
    jump_trajectory : the mass-spring trajectory for ``--jump``
        (:class:`snapjump_cli.jump.trajectory.JumpTrajectory`)
    imperfect : the imperfect actuator traced to its snap (``--imperfection``,
        :class:`snapjump_cli.fe.branch.imperfection.ImperfectResult`): the p-V plot adds its path and snap;
        without a followed branch, ``--shapes``, ``--animation``, ``--export`` and ``--csv`` show it
        as the actuator (its path from rest, its snap, its lower state)

    Returns
    -------
    list of Path
        The files (and the ``.pvd``'s step folder) written.
    """
    from snapjump_cli.geometry.caps import CapScene

    wanted = {k: v for k, v in paths.items() if v is not None}
    if not wanted:
        return []
    title = scene_title(scene)
    vsym = "ΔV" if isinstance(scene, CapScene) else "V"
    steps = act = None
    if set(wanted) & {"--csv", "--shapes", "--animation", "--export"}:
        from snapjump_cli.viz.states import path_steps

        steps = path_steps(res)
    from snapjump_cli.viz.actuator import actuator_path, branch_of, branch_rows

    branch, kind = branch_of(res)
    if branch is None and imperfect is not None:  # the imperfect actuator snaps as drawn
        branch, kind = imperfect, "imperfect"
    if set(wanted) & {"--shapes", "--animation"} or (branch is not None and "--export" in wanted):
        act = actuator_path(res, steps, branch=branch, kind=kind or "followed")
    mesh = res.model.mesh if res.model is not None else None
    jobs: list[tuple[str, Path, Callable[[Path], object]]] = []
    air = getattr(res, "air", None)  # inflated with air (snapjump_cli.fe.axisym.air_snap): its snap, and V_d per step
    if "--csv" in wanted:
        columns = steps.columns()
        columns["branch"] = ["axisymmetric"] * len(steps)
        if air is not None:
            columns["V_disp_m3"] = list(air.dispensed(steps.V_m3, steps.p_Pa, res.model))
        if getattr(res, "margins", None) is not None:  # every step's margins (snapjump_cli.fe.stability.margins)
            from snapjump_cli.fe.stability.margins import state_margins

            n_max = res.margins.shape[1] - 2
            table = np.array([state_margins(res.model, u, p, n_max) for u, p in zip(steps.u, steps.p_scaled)])
            for n in range(n_max + 1):
                columns[f"margin_n{n}"] = list(table[:, n])
        if branch is not None:  # the followed branch's points after the axisymmetric path's
            rows = branch_rows(res, branch, kind)
            n0, n1 = len(steps), len(rows["p_Pa"])
            for key in columns:
                if key in rows:
                    columns[key] = list(columns[key]) + list(rows[key])
                elif key == "step":
                    columns[key] = list(columns[key]) + list(range(n0, n0 + n1))
                elif key == "branch":
                    columns[key] = list(columns[key]) + [kind] * n1
                else:
                    columns[key] = list(columns[key]) + [float("nan")] * n1
        jobs.append(("--csv", wanted["--csv"], lambda t: _write_csv(columns, t)))
    if "--plot" in wanted:
        from snapjump_cli.viz.figures import plot_air_curves, plot_pv_curve

        bcurve = None
        if getattr(res, "follow", None) is not None:  # the followed branch beside the axisymmetric path
            from snapjump_cli.fe.branch.metrics import branch_curve

            bcurve = branch_curve(res.follow)
        if air is None:
            icurve = imperfect_curve(imperfect) if imperfect is not None else None
            jobs.append(("--plot", wanted["--plot"], lambda t: plot_pv_curve(
                res.curve, metrics, t, title=title, branch=bcurve, normalised=normalised, imperfect=icurve)))
        else:
            jobs.append(("--plot", wanted["--plot"], lambda t: plot_air_curves(res.curve, metrics, t, title=title)))
    if "--shapes" in wanted:
        from snapjump_cli.viz.shapes import actuator_shape_states, key_shape_states, plot_shapes

        if act.followed:  # the states the actuator takes: both meridian sections, the 3D stretch
            shape_states = actuator_shape_states(act)
        else:
            shape_states = key_shape_states(steps, mesh.nodes)
        jobs.append(("--shapes", wanted["--shapes"], lambda t: plot_shapes(
            mesh, shape_states, t, title=title, volume_symbol=vsym)))
    if "--animation" in wanted:
        from snapjump_cli.viz.animation import write_animation

        anim_branch = None
        if branch is not None and kind == "followed":
            from snapjump_cli.fe.branch.metrics import branch_curve

            anim_branch = branch_curve(branch)
        jobs.append(("--animation", wanted["--animation"], lambda t: write_animation(
            mesh, act, t, title=title, volume_symbol=vsym, curve={"V_m3": steps.V_m3, "p_Pa": steps.p_Pa},
            branch=anim_branch)))
    if "--jump" in wanted:
        from snapjump_cli.viz.jump_plot import plot_jump

        jobs.append(("--jump", wanted["--jump"], lambda t: plot_jump(jump_trajectory, metrics, t, title=title)))
    from snapjump_cli.files import AtomicFiles, OutputError, os_error_reason

    stage = AtomicFiles()  # a full disk or an I/O error: OutputError, one line naming the file (exit 2)
    try:
        for opt, final, job in jobs:
            stage.add(final, job)
        if "--export" in wanted:
            from snapjump_cli.viz.export import export_steps

            try:
                if act is not None and act.followed:
                    from snapjump_cli.viz.export import FOLLOWED_SECTORS, export_actuator

                    export_actuator(res, act, wanted["--export"], sectors=revolve or FOLLOWED_SECTORS, stage=stage)
                else:
                    export_steps(res, steps, wanted["--export"], revolve=revolve, stage=stage)
            except OSError as e:
                if isinstance(e, OutputError):
                    raise
                why = os_error_reason(e)
                raise OutputError(f"{wanted['--export']}: cannot write it ({why}); nothing written", e.errno,
                                  why) from None
        written = stage.commit()
    except BaseException:
        stage.discard()
        raise
    for f in written:
        log.info("wrote %s", f)
    return written
