"""The files ``snapjump curve`` writes for one solved scene, all at once: ``--csv`` (the steps),
``--plot`` (the p-V curve), ``--shapes``, ``--animation`` and ``--export`` (``--revolve``).

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

__all__ = ["OUTPUT_SUFFIXES", "check_outputs", "write_outputs"]

log = logging.getLogger(__name__)

#: The file suffixes of each output option.
OUTPUT_SUFFIXES = {"--csv": (".csv",), "--plot": (".png",), "--shapes": (".png",), "--animation": (".gif",),
                   "--export": (".pvd", ".xdmf")}
_NEEDS = {"--plot": "matplotlib", "--shapes": "matplotlib", "--animation": "matplotlib", "--export": "meshio"}
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


def write_outputs(res, scene, metrics: dict, paths: dict[str, Path | None], revolve: int = 0) -> list[Path]:
    """Write every requested output of a solved scene, all or none (module docstring).

    Parameters
    ----------
    res : the :class:`~snapjump_cli.fe.solve.SceneResult`
    scene : its scene (the title, and ``ΔV`` for a single cap's supplied volume)
    metrics : the reported metrics (JSON-ready), for the p-V plot
    paths : option -> path (``--csv``, ``--plot``, ``--shapes``, ``--animation``, ``--export``)
    revolve : sectors of the exported solid of revolution (0: the section)

    Returns
    -------
    list of Path
        The files (and the ``.pvd``'s step folder) written.
    """
    from snapjump_cli.geometry.caps import CapScene

    wanted = {k: v for k, v in paths.items() if v is not None}
    if not wanted:
        return []
    title = getattr(scene, "name", None) or ""
    if isinstance(scene, CapScene):
        title = title or f"{scene.kind} cap, theta {scene.theta_deg:g} deg, eta {scene.eta:g}"
    elif not title:
        title = (f"design ({scene.eta_i:g}, {scene.theta_i_deg:g}, {scene.eta_o:g}, {scene.theta_o_deg:g}, "
                 f"{scene.mu_ratio:g})")
    else:
        title = f"design {title}"
    vsym = "ΔV" if isinstance(scene, CapScene) else "V"
    steps = None
    if set(wanted) & {"--csv", "--shapes", "--animation", "--export"}:
        from snapjump_cli.viz.states import path_steps

        steps = path_steps(res)
    mesh = res.model.mesh if res.model is not None else None
    jobs: list[tuple[str, Path, Callable[[Path], object]]] = []
    air = getattr(res, "air", None)  # inflated with air (snapjump_cli.fe.axisym.air_snap): its snap, and V_d per step
    if "--csv" in wanted:
        columns = steps.columns()
        if air is not None:
            columns["V_disp_m3"] = list(air.dispensed(steps.V_m3, steps.p_Pa, res.model))
        if getattr(res, "margins", None) is not None:  # every step's margins (snapjump_cli.fe.stability.margins)
            from snapjump_cli.fe.stability.margins import state_margins

            n_max = res.margins.shape[1] - 2
            table = np.array([state_margins(res.model, u, p, n_max) for u, p in zip(steps.u, steps.p_scaled)])
            for n in range(n_max + 1):
                columns[f"margin_n{n}"] = list(table[:, n])
        jobs.append(("--csv", wanted["--csv"], lambda t: _write_csv(columns, t)))
    if "--plot" in wanted:
        from snapjump_cli.viz.figures import plot_air_curves, plot_pv_curve

        branch = None
        if getattr(res, "follow", None) is not None:  # the followed branch beside the axisymmetric path
            from snapjump_cli.fe.branch.metrics import branch_curve

            branch = branch_curve(res.follow)
        if air is None:
            jobs.append(("--plot", wanted["--plot"],
                         lambda t: plot_pv_curve(res.curve, metrics, t, title=title, branch=branch)))
        else:
            jobs.append(("--plot", wanted["--plot"], lambda t: plot_air_curves(res.curve, metrics, t, title=title)))
    if "--shapes" in wanted:
        from snapjump_cli.viz.shapes import followed_shape_states, key_shape_states, plot_shapes

        shape_states = key_shape_states(steps, mesh.nodes)
        if getattr(res, "follow", None) is not None:  # the followed snap's states, both meridian sections
            shape_states += followed_shape_states(res.follow)
        jobs.append(("--shapes", wanted["--shapes"], lambda t: plot_shapes(
            mesh, shape_states, t, title=title, volume_symbol=vsym)))
    if "--animation" in wanted:
        from snapjump_cli.viz.animation import write_animation

        jobs.append(("--animation", wanted["--animation"],
                     lambda t: write_animation(mesh, steps, t, title=title, volume_symbol=vsym)))
    from snapjump_cli.files import AtomicFiles, OutputError, os_error_reason

    stage = AtomicFiles()  # a full disk or an I/O error: OutputError, one line naming the file (exit 2)
    try:
        for opt, final, job in jobs:
            stage.add(final, job)
        if "--export" in wanted:
            from snapjump_cli.viz.export import export_steps

            try:
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
