"""``snapjump report``: one self-contained HTML page for a design or for a result file.

* ``snapjump report --design D -o d.html`` (any scene of ``curve``; ``--harmonics N --follow``):
  the design card: the p-V curve in kPa and ml with the snap, the states, ΔE, Δy_pole, h_imp, the
  jump (the model of ``rank``), whether the branch was followed, the inputs, the command and the
  version. The scene is solved as ``snapjump curve`` solves it.
* ``snapjump report RESULTS.parquet -o r.html``: the sweep report: the ranking (sortable), Fig.
  4A and 4C, the jump against each parameter, the flags, why designs were not solved, the config
  and the provenance (a file not yet ranked is ranked with ``rank``'s defaults; the file is not
  changed).

The page needs no network to be viewed: figures are embedded as base64 PNG, and the ranking's
sorting is a few lines of JavaScript in the page (:mod:`snapjump_cli.report`).
"""
from __future__ import annotations

import sys
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

import click

from snapjump_cli.cli import verbosity_options
from snapjump_cli.commands.options import (
    mesh_options,
    mesh_settings_from_options,
    pick_mesh_options,
    pick_scene_options,
    scene_from_options,
    scene_options,
)
from snapjump_cli.errors import BadInput

__all__ = ["command", "main"]


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _command_line() -> str | None:
    """The command line, when run as ``snapjump`` (not from Python)."""
    return "snapjump " + " ".join(sys.argv[1:]) if sys.argv and "snapjump" in Path(sys.argv[0]).name else None


def _design_html(kw: dict, harmonics: int, follow: bool, time_limit_s: float) -> str:
    from snapjump_cli.commands.curve import _inputs, _provenance, jump_keys, to_jsonable
    from snapjump_cli.fe.solve import SolveFailed, solve_checked
    from snapjump_cli.jump import JumpParams
    from snapjump_cli.report.pages import design_page, figure_png
    from snapjump_cli.settings import SolverSettings
    from snapjump_cli.viz.figures import plot_pv_curve
    from snapjump_cli.viz.jump_plot import plot_jump
    from snapjump_cli.viz.outputs import scene_title

    if follow and harmonics < 1:
        raise BadInput("--follow needs --harmonics N with N >= 1 (the check that finds the bifurcation)")
    scene = scene_from_options(**pick_scene_options(kw))
    ms = mesh_settings_from_options(**pick_mesh_options(kw))
    ss = SolverSettings(harmonics=harmonics, follow=follow, time_limit_s=time_limit_s)
    try:
        res = solve_checked(scene, ms, ss)
    except SolveFailed as exc:
        raise click.ClickException(f"solve failed: {exc}") from None
    params = JumpParams()
    m = to_jsonable(res.metrics)
    jk, trajectory = jump_keys(m, params, getattr(scene, "R_i", None) or getattr(scene, "R", None))
    m.update(jk)
    m = to_jsonable(m)
    m["inputs"] = _inputs(scene, ms, ss, params)
    m.update(_provenance())
    title = scene_title(scene)
    branch = None
    if getattr(res, "follow", None) is not None:
        from snapjump_cli.fe.branch.metrics import branch_curve

        branch = branch_curve(res.follow)
    figs = {"pv": figure_png(lambda p: plot_pv_curve(res.curve, m, p, title=title, branch=branch))}
    if res.model is not None and res.path is not None:
        from snapjump_cli.viz.actuator import actuator_path
        from snapjump_cli.viz.shapes import actuator_shape_states, key_shape_states, plot_shapes
        from snapjump_cli.viz.states import path_steps

        steps = path_steps(res)
        act = actuator_path(res, steps)
        states = actuator_shape_states(act) if act.followed else key_shape_states(steps, res.model.mesh.nodes)
        figs["shapes"] = figure_png(lambda p: plot_shapes(res.model.mesh, states, p, title=title, dpi=110))
    if trajectory is not None:
        figs["jump"] = figure_png(lambda p: plot_jump(trajectory, m, p, title=title))
    return design_page(title, m, figs, m.get("command"), _now())


def _results_html(path: Path, top: int) -> str:
    from snapjump_cli.commands.info import summarise
    from snapjump_cli.jump.rank import RankInputError, rank_results
    from snapjump_cli.report.pages import figure_png, results_page
    from snapjump_cli.sweep import results as res
    from snapjump_cli.viz.figures import plot_fig4a, plot_fig4c, plot_jump_vs_parameters

    summary = summarise(path)
    df = res.read_results(path)
    if "rank" not in df.columns or "y_jump_m" not in df.columns:
        try:
            df = rank_results(df)
        except RankInputError as e:
            raise BadInput(f"{path}: {e}") from None
    figs = {"fig4a": figure_png(lambda p: plot_fig4a(df, p)), "fig4c": figure_png(lambda p: plot_fig4c(df, p)),
            "params": figure_png(lambda p: plot_jump_vs_parameters(df, p))}
    return results_page(str(path), df, summary, figs, top, _command_line(), _now())


@click.command("report", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("results", required=False, type=click.Path(path_type=Path))
@scene_options
@mesh_options
@click.option("-o", "--output", "output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The HTML page to write (.html).")
@click.option("--harmonics", type=click.IntRange(0, 64), default=0, show_default=True, metavar="N",
              help="A design: check its path against the harmonics n = 1..N (as curve --harmonics).")
@click.option("--follow", is_flag=True, help="A design, with --harmonics: report the followed snap (as curve --follow).")
@click.option("--time-limit", "time_limit_s", type=click.FloatRange(min=0, min_open=True, max=1e9), default=300.0,
              show_default=True, metavar="SECONDS", help="A design: CPU seconds the solve may take.")
@click.option("--top", type=click.IntRange(min=1), default=30, show_default=True, metavar="N",
              help="A result file: rows of the ranking shown.")
@click.option("--overwrite", is_flag=True, help="Replace an existing page (refused by default).")
@verbosity_options
def command(results: Path | None, output: Path, harmonics: int, follow: bool, time_limit_s: float, top: int,
            overwrite: bool, **kw) -> None:
    """Write one self-contained HTML page: a design card (a scene, solved as curve solves it) or
    the report of a result file (ranking, Fig. 4A/4C, parameter plots, flags, provenance).

    \b
    Examples:
      snapjump report --design D -o d.html
      snapjump report --design B --harmonics 4 --follow -o b.html
      snapjump report results.parquet -o results.html
    """
    from snapjump_cli.files import check_writable, write_atomic

    if output.suffix.lower() not in (".html", ".htm"):
        raise BadInput(f"-o/--output {output}: expected an .html file")
    if not output.parent.exists():
        raise BadInput(f"-o/--output {output}: directory {output.parent} does not exist")
    check_writable(output, BadInput, overwrite=overwrite)
    scene_given = any(kw.get(k) is not None for k in ("design", "eta_i", "theta_i", "eta_o", "theta_o", "cap"))
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise BadInput("report needs matplotlib, which is not installed (pip install 'snapjump[plots]')") from None
    if results is not None:
        if scene_given:
            raise BadInput("report: give a result file or a scene (--design ...), not both")
        if not results.exists():
            raise BadInput(f"{results}: file not found")
        if not results.is_file():
            raise BadInput(f"{results}: expected a parquet file")
        page = _results_html(results, top)
    else:
        if not scene_given:
            raise BadInput("report: give a result file (RESULTS.parquet) or a scene (--design NAME, ...)")
        page = _design_html(kw, harmonics, follow, time_limit_s)
    write_atomic(output, lambda tmp: Path(tmp).write_text(page, encoding="utf-8"))
    click.echo(f"wrote {output}", err=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump report`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["report", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
