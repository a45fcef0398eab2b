"""``snapjump optimize SPEC.yaml``: search the continuous design space for the highest jump."""
from __future__ import annotations

import json
import logging
import math
import sys
from contextlib import ExitStack
from pathlib import Path
from typing import Any, Sequence

import click

from snapjump_cli.cli import injected, is_quiet, verbosity_options
from snapjump_cli.commands._stop import sigterm_as_interrupt
from snapjump_cli.errors import BadInput
from snapjump_cli.sweep.checks import JOBS_PER_CORE, max_jobs

__all__ = ["command", "main"]

log = logging.getLogger(__name__)

_HELP = """Search the box of SPEC.yaml for the design with the highest jump, then confirm it.

\b
SPEC.yaml: `bounds:` for eta_i, theta_i (deg), eta_o, theta_o (deg) and mu_ratio, each
[lo, hi] or a fixed value; optional objective (y_jump_m, default, or dE_J), budget
(number of solves), seed, method (pattern, default, or differential_evolution),
search {starts, init, step, min_step, spread, popsize}, confirm {tolerance, candidates}
(or false), jump {rho, c_d, alpha}, and the sweep's R_i, materials, ring, mesh, solver,
output, n_jobs, chunk_size (see configs/optimize.yaml and docs/optimize.md).

The search (parallel pattern search from the best rows of --from inside the box, or from a
seeded sample) solves its designs in batches with the sweep's executor into
<OUTPUT stem>.evals.parquet, so running the same command again resumes: designs already
solved are not solved again, and the same seed gives the same answer. Designs with invalid
geometry, no snap, a failed solve or the mesh_sensitive flag are never chosen.

The best designs are then re-solved on a finer mesh (nt + 1, elements half as long along
the arcs) into <OUTPUT stem>.confirm.parquet until one holds its objective within the
tolerance (2 %). OUTPUT gets every evaluation (the sweep's columns plus iteration and
stage); the plots <OUTPUT stem>.progress.png and .path.png go next to it (the table and
the plots are written together, all or none). OUTPUT is locked while the run lasts
(OUTPUT.lock, as a sweep's); an existing OUTPUT is replaced only if it is a run of the same
spec (its budget may differ), and so are the plots, unless --overwrite is given.

Exit codes: 0 done, 1 no design could be confirmed (or none is feasible) or the run failed,
2 bad input (spec errors name the file and the key path), 130 interrupted.
"""


def _fmt(x: Any, scale: float = 1.0, digits: int = 1) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x * scale:.{digits}f}"


def _design(d: dict | tuple | None) -> str:
    if d is None:
        return "-"
    if not isinstance(d, dict):
        from snapjump_cli.optimize import PARAMETERS

        d = dict(zip(PARAMETERS, d))
    return ", ".join(f"{k} {v:.4g}" for k, v in d.items())


def _text(summary: dict, result: Any, output: Path, files: list[Path], from_path: Path | None) -> str:
    s = summary
    lines = [
        f"optimize {result.spec.source}: method {s['method']}, objective {s['objective']}, seed {s['seed']}: "
        f"{s['n_evaluations']} solves of {s['budget']} ({s['n_resumed']} found in the cache, "
        f"{s['n_invalid_geometry']} invalid geometries skipped), {s['iterations']} iterations, "
        f"{result.wall_s:.0f} s",
    ]
    if s["best"] is None:
        lines.append("best: none (no feasible design" + (" held on the finer mesh)" if s["confirm_tried"] else ")"))
    else:
        lines.append(f"best: {_design(s['best'])}")
        conf = ""
        if s["y_jump_confirmed_m"] is not None and s["y_jump_m"]:
            m = s["confirm_mesh"]
            rel = (s["y_jump_confirmed_m"] / s["y_jump_m"] - 1) * 100
            conf = (f" (confirmed {_fmt(s['y_jump_confirmed_m'], 1e3)} mm on mesh order {m['order']}, nt {m['nt']}, "
                    f"aspect {m['aspect']:.3g}: {rel:+.2f} %)")
        lines.append(f"  y_jump {_fmt(s['y_jump_m'], 1e3)} mm{conf}; dE {_fmt(s['dE_J'], 1e3)} mJ, "
                     f"dy_pole {_fmt(s['dy_pole_m'], 1e3, 2)} mm, h_imp {_fmt(s['h_imp_m'], 1e3, 2)} mm"
                     + ("; search converged there" if s["converged"] else ""))
    base = s["baseline_y_jump_m"]
    if base is not None:
        where = f"--from {from_path} inside the box" if from_path is not None and s["baseline_design"] else "the start points"
        gain = ""
        ref = s["y_jump_confirmed_m"] if s["y_jump_confirmed_m"] is not None else s["y_jump_m"]
        if ref is not None and base > 0:
            gain = f"; best {'(confirmed) ' if s['y_jump_confirmed_m'] is not None else ''}{(ref / base - 1) * 100:+.1f} %"
        lines.append(f"baseline (best of {where}): {_fmt(base, 1e3)} mm at {_design(s['baseline_design'])}{gain}")
    if len(s["confirm_tried"]) > 1 or (s["confirm_tried"] and not s["confirmed"]):
        for c in s["confirm_tried"]:
            lines.append(f"  confirmation of {_design(c['design'])}: {_fmt(c['search'], 1e3)} -> "
                         f"{_fmt(c['finer'], 1e3)} ({'holds' if c['held'] else 'does not hold'})")
    sens = s["sensitivity"]
    if sens:
        h = sens["h"]
        parts = [f"{k} {_fmt(v, 1e3) if v is not None else 'infeasible'}" for k, v in sens.items() if k not in ("h", "f")]
        lines.append(f"last poll around it (step {h:.4g} of the box; {_fmt(sens['f'], 1e3)} at the centre): "
                     + ", ".join(parts))
    lines.append(f"wrote {output}")
    lines += [f"wrote {f}" for f in files]
    return "\n".join(lines)


@click.command("optimize", help=_HELP, short_help="Search the design space for the highest jump (resumable).")
@click.argument("spec", metavar="SPEC.yaml", type=click.Path(dir_okay=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Result parquet file (every evaluation). [default: `output` of the spec, else "
                   "results/<SPEC stem>.parquet]")
@click.option("-j", "--jobs", "n_jobs", type=int, default=None, metavar="N",
              help=f"Worker processes (joblib n_jobs: -1 = every core), at most {JOBS_PER_CORE} per core "
                   f"(here {max_jobs()}). [default: `n_jobs` of the spec, else -1]")
@click.option("--budget", type=click.IntRange(min=1, max=100_000), default=None, metavar="N",
              help="Number of solves (overrides `budget:` of the spec), at most 100000.")
@click.option("--from", "from_path", type=click.Path(path_type=Path), default=None, metavar="RESULTS.parquet",
              help="Sweep results whose best rows inside the box seed the search (a parquet file, or the "
                   ".parts folder of an unfinished sweep).")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Summary format on stdout.")
@click.option("--plots/--no-plots", default=True, show_default=True,
              help="Write <OUTPUT stem>.progress.png and <OUTPUT stem>.path.png (needs matplotlib).")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress on stderr: a bar on a terminal, a plain line every 30 s otherwise. -q hides it.")
@click.option("--overwrite", is_flag=True,
              help="Replace an OUTPUT (and plots) that is not a run of this spec: another spec's run, a sweep's "
                   "results, any other file (refused by default).")
@verbosity_options
def command(spec: Path, output: Path | None, n_jobs: int | None, budget: int | None, from_path: Path | None,
            fmt: str, plots: bool, progress: bool, overwrite: bool) -> None:
    from snapjump_cli.files import check_writable, follow_links
    from snapjump_cli.optimize import OptimizeInputError, cache_paths, check_output, load_spec, read_from
    from snapjump_cli.sweep.config import ConfigError
    from snapjump_cli.sweep.run import SweepInputError
    from snapjump_cli.sweep.storage import OutputLock

    try:
        sp = load_spec(spec)
    except ConfigError as e:
        raise BadInput(str(e)) from None
    from snapjump_cli.sweep.checks import jobs_error

    if n_jobs is not None and (why := jobs_error(n_jobs)):
        raise BadInput(f"-j/--jobs: {why}")
    out = output if output is not None else sp.output
    if out.exists() and out.is_dir():
        raise BadInput(f"-o/--output: {out} is a directory, expected a parquet file path")
    check_writable(out, BadInput)  # not a FIFO, a device, a system folder, ...; a link: its target is written
    out = follow_links(out)
    from_df = None
    if from_path is not None:
        if from_path.resolve() in {p.resolve() for p in (out, *cache_paths(out))}:
            raise BadInput(f"--from: {from_path} is this run's own output")
        try:
            from_df = read_from(from_path)
        except OptimizeInputError as e:
            raise BadInput(str(e)) from None

    with ExitStack() as lock:
        try:
            out.parent.mkdir(parents=True, exist_ok=True)  # as sweep and rank do: the lock lives beside the output
        except OSError as e:
            raise BadInput(f"-o/--output: {out}: cannot create its folder ({e.strerror})") from None
        try:
            lock.enter_context(OutputLock(out, command="optimize"))
            check_output(out, sp, overwrite)
        except (SweepInputError, OptimizeInputError) as e:
            raise BadInput(str(e)) from None
        _run(sp, out, n_jobs, budget, from_path, from_df, fmt, plots, progress)


def _run(sp: Any, out: Path, n_jobs: int | None, budget: int | None, from_path: Path | None, from_df: Any, fmt: str,
         plots: bool, progress: bool) -> None:
    """The run itself, under the output's lock: search, confirm, write the table and plots, report."""
    from snapjump_cli.files import AtomicFiles, describe_os_error, remedy
    from snapjump_cli.optimize import OptimizeInputError, cache_paths, make_plots, run_optimize, write_result
    from snapjump_cli.sweep.run import SweepError, SweepInputError

    bar = None
    stack = ExitStack()
    if progress and not is_quiet():
        from snapjump_cli.sweep.run import make_progress

        bar = make_progress(budget if budget is not None else sp.budget, 0, stack, desc="optimize", unit="solve")

    def on_batch(n: int, total: int, best: float) -> None:
        if bar is None:
            return
        bar.update(max(0, n - bar.n))
        if math.isfinite(best):
            unit = " mm" if sp.objective == "y_jump_m" else " mJ"
            bar.set_postfix({"best": f"{best * 1e3:.1f}{unit}"}, refresh=False)

    kept = f"finished solves are kept in {cache_paths(out)[0]} (and its .parts)"
    stopped = f"interrupted: {kept}; run the same command again to resume"
    with sigterm_as_interrupt(stopped):  # SIGTERM -> same clean stop as Ctrl-C (finished solves kept)
        try:
            result = run_optimize(sp, output=out, n_jobs=n_jobs, budget=budget, from_df=from_df, on_batch=on_batch,
                                  solve_fn=injected("solve_fn"), warm_up_fn=injected("warm_up_fn"))
        except (SweepInputError, OptimizeInputError) as e:
            raise BadInput(str(e)) from None
        except SweepError as e:
            raise click.ClickException(str(e)) from None
        except OSError as e:  # a full disk, an I/O error: one line, exit 2
            raise BadInput(f"{describe_os_error(e)}; the {kept}: {remedy(e)} and run the same command "
                           f"again to resume") from None
        finally:
            if bar is not None:
                bar.close()
            stack.close()

    files: list[Path] = []
    if plots:
        try:
            import matplotlib  # noqa: F401
        except ImportError as e:
            log.warning("no plots: they need matplotlib (pip install 'snapjump[plots]'): %s", e)
            plots = False
    try:
        with AtomicFiles() as batch:  # the table and its plots, all or none
            batch.add(out, lambda tmp: write_result(result, tmp, {"from": None if from_path is None else str(from_path),
                                                                  "output": str(out)}))
            if plots:
                files = make_plots(result, out, batch=batch)
    except OSError as e:
        raise BadInput(f"{describe_os_error(e)}; nothing was written, the {kept}: run the same command again "
                       f"to write the result") from None
    summary = result.summary()
    if fmt == "json":
        summary.update(output=str(out), plots=[str(f) for f in files])
        click.echo(json.dumps(summary, indent=2))
    else:
        click.echo(_text(summary, result, out, files, from_path))
    if result.best is None:
        why = ("no candidate held its objective on the finer mesh" if result.confirm_tried
               else "no feasible design was found")
        raise click.ClickException(f"{why}; every evaluation is in {out}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump optimize`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["optimize", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
