"""``snapjump sweep GRID.yaml``: solve a grid of designs in parallel into a parquet file."""
from __future__ import annotations

import logging
import sys
from pathlib import Path
from typing import Sequence

import click

from snapjump_cli.cli import injected, is_quiet, verbosity_options
from snapjump_cli.commands._stop import sigterm_as_interrupt
from snapjump_cli.errors import BadInput
from snapjump_cli.sweep.checks import JOBS_PER_CORE, max_jobs

__all__ = ["command", "main"]

log = logging.getLogger(__name__)

_HELP = """Solve the designs in GRID.yaml (a grid or a list of points) in parallel into a parquet file.

\b
GRID.yaml needs only a `grid:` section with the five axes eta_i, theta_i (deg), eta_o,
theta_o (deg) and mu_ratio, each a list of values or {start, stop, num}; the designs are
their Cartesian product. Instead of `grid:`, `points:` lists the designs one by one
({eta_i, theta_i, eta_o, theta_o, mu_ratio} each) or names a CSV/parquet file of them
(a result file works). Optional keys: R_i, materials {mu_i, J_m},
ring {t_ring_frac, w_ring_frac}, mesh {order, nt, aspect}, solver {tol, ds0, ...},
output, n_jobs, chunk_size (see configs/paper_grid.yaml).

One row per design: inputs, R_o and Delta, every solver metric, status (ok, no_snap,
invalid_geometry, failed), the error text, timings and the mesh size. Invalid designs
are recorded, never meshed; a design that fails never stops the sweep.

Finished rows are written in chunks to OUTPUT.parts/ (each part atomically) and merged
into OUTPUT at the end. Running the same command again resumes: designs already
recorded (same parameters and mesh/solver settings) are skipped. A second sweep into the
same output is refused while the first runs (OUTPUT.lock names it); an output holding rows
of another grid, mesh, solver or material is refused unless --append is given. Every row
records its code version, commit, mesh and solver settings.

Exit codes: 0 done (even if some designs failed), 1 the sweep could not run,
2 bad input (config errors name the file and the key path), 130 interrupted.
"""


@click.command("sweep", help=_HELP, short_help="Solve a YAML grid of designs into a parquet file.")
@click.argument("grid", metavar="GRID.yaml", type=click.Path(dir_okay=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Result parquet file. [default: `output` of the config, else results/<GRID stem>.parquet]")
@click.option("-j", "--jobs", "n_jobs", type=int, default=None, metavar="N",
              help=f"Worker processes (joblib n_jobs: -1 = every core, 1 = in this process), at most "
                   f"{JOBS_PER_CORE} per core (here {max_jobs()}). [default: `n_jobs` of the config, else -1]")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Run on a dask.distributed cluster at ADDRESS (e.g. tcp://10.0.0.5:8786) through "
                   "joblib's dask backend instead of local processes. Needs snapjump[dask].")
@click.option("--chunk-size", type=click.IntRange(min=1, max=100_000), default=None, metavar="N",
              help="Finished designs per part file, at most 100000. [default: `chunk_size` of the config, else 16]")
@click.option("--retry-failed", is_flag=True, help="Solve designs recorded as failed again.")
@click.option("--append", is_flag=True,
              help="Add to an output that holds rows of another grid, mesh, solver or material "
                   "(refused by default, so that results are never mixed by accident).")
@click.option("--max-designs", type=click.IntRange(min=1), default=None, metavar="N",
              help="Refuse configs with more designs than N. [default: 100000]")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress on stderr: a bar (ETA, counts of ok / no-snap / invalid / failed) on a "
                   "terminal, a plain line every 30 s otherwise. -q hides it.")
@verbosity_options
def command(grid: Path, output: Path | None, n_jobs: int | None, scheduler: str | None,
            chunk_size: int | None, retry_failed: bool, append: bool, max_designs: int | None,
            progress: bool) -> None:
    from snapjump_cli.files import describe_os_error, follow_links, remedy
    from snapjump_cli.sweep.config import ConfigError, load_config
    from snapjump_cli.sweep.run import MAX_DESIGNS, SweepError, SweepInputError, parts_dir, run_sweep

    try:
        config = load_config(grid, max_designs or MAX_DESIGNS)
    except ConfigError as e:
        raise BadInput(str(e)) from None
    from snapjump_cli.sweep.checks import jobs_error

    if n_jobs is not None and (why := jobs_error(n_jobs)):
        raise BadInput(f"-j/--jobs: {why}")
    out = output if output is not None else config.output

    parts = parts_dir(follow_links(out))
    stopped = f"interrupted: finished designs are kept in {parts}; run the same command again to resume"
    with sigterm_as_interrupt(stopped):  # SIGTERM -> same clean stop as Ctrl-C (finished rows kept)
        try:
            quiet = is_quiet()
            summary = run_sweep(config, output=out, n_jobs=n_jobs, scheduler=scheduler,
                                progress=progress and not quiet, retry_failed=retry_failed, chunk_size=chunk_size,
                                append=append, max_designs=max_designs or MAX_DESIGNS,
                                solve_fn=injected("solve_fn"), warm_up_fn=injected("warm_up_fn"),
                                announce=None if quiet else (lambda line: click.echo(line, err=True)))
        except SweepInputError as e:
            raise BadInput(str(e)) from None
        except SweepError as e:
            raise click.ClickException(str(e)) from None
        except OSError as e:  # a full disk, an I/O error: one line, exit 2; what was written is kept
            raise BadInput(f"{describe_os_error(e)}; the finished designs are kept (in {parts}); {remedy(e)} "
                           f"and run the same command again to resume") from None
    c = summary.counts
    click.echo(
        f"{summary.output}: {summary.n_designs} designs ({summary.n_resumed} resumed, {summary.n_solved} solved "
        f"in {summary.wall_s:.1f} s): ok {c.get('ok', 0)}, no_snap {c.get('no_snap', 0)}, "
        f"invalid_geometry {c.get('invalid_geometry', 0)}, failed {c.get('failed', 0)}"
    )
    if (c.get("invalid_geometry") or c.get("failed")) and not is_quiet():
        _echo_reasons(summary.output)


def _echo_reasons(output: Path) -> None:
    """The reasons of the invalid and failed designs of ``output``, grouped (they are in its
    ``error`` column; a newcomer would not look there)."""
    from snapjump_cli.sweep import results as res

    try:
        df = res.read_table(output, columns=["status", "error"]).to_pandas(use_threads=res.ARROW_THREADS)
    except (res.ResultsFileError, OSError) as e:  # the summary above stands; the reasons are extra
        log.warning("could not read the reasons back from %s: %s", output, e)
        return
    for line in res.failure_reasons(df, source=output):
        click.echo(line, err=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump sweep`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["sweep", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
