"""``snapjump rank RESULTS.parquet``: jump height of every design, ranked."""
from __future__ import annotations

import json
import logging
import sys
from datetime import datetime, timezone
from pathlib import Path
from contextlib import ExitStack
from typing import Any, Sequence

import click

from snapjump_cli.cli import is_quiet, verbosity_options
from snapjump_cli.errors import BadInput
from snapjump_cli.settings import JUMP_ALPHA, JUMP_C_D, JUMP_RHO

__all__ = ["command", "main"]

log = logging.getLogger(__name__)

_HELP = """Apply the mass-spring jump model to sweep results and rank the designs.

\b
For every `ok` row: masses m_i, m_o = rho * (V_inner_solid_m3, V_outer_solid_m3), spring
k_s = 2 dE / dy_pole^2 precompressed by dy_pole, release from h_imp_m, and y_jump_m = the
highest height of the inner pole (docs/physics.md section 6). `no_snap` rows get
y_jump_m = 0 with the reason; invalid and failed rows get NaN.

Prints the top-N table (lengths in mm, energies in mJ; with the flags self_crossing,
mesh_sensitive, jump_complete and the lower-state method), or CSV / JSON with --format,
writes the ranked table (sorted by y_jump_m, column `rank`), atomically, and with --plots draws Fig. 4A (energy release
vs pole travel, by mu ratio), Fig. 4C (jump height over that plane) and the jump height
against each design parameter.

Existing output files are not replaced unless --overwrite is given (the same in every
command); nothing is written when any output place is unusable.
"""


@click.command("rank", help=_HELP, short_help="Rank sweep results by the jump height of the mass-spring model.")
@click.argument("results", metavar="RESULTS.parquet", type=click.Path(path_type=Path))
@click.option("--top", "top", type=click.IntRange(min=0), default=10, show_default=True, metavar="N",
              help="Rows of the printed table.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Ranked table: a .parquet file (every column, with provenance) or a .csv file. "
                   "[default: <RESULTS stem>.ranked.parquet next to RESULTS]")
@click.option("--plots", "plots_dir", type=click.Path(file_okay=False, path_type=Path), default=None, metavar="DIR",
              help="Write fig4a.png, fig4c.png and jump_vs_parameters.png into DIR (needs matplotlib).")
@click.option("--rho", type=float, default=JUMP_RHO, show_default=True, help="Rubber density [kg/m^3].")
@click.option("--c-d", "c_d", type=float, default=JUMP_C_D, show_default=True, help="Dashpot coefficient [kg/s].")
@click.option("--alpha", type=float, default=JUMP_ALPHA, show_default=True, help="Ground restitution coefficient, in [0, 1].")
@click.option("--format", "fmt", type=click.Choice(["text", "csv", "json"]), default="text", show_default=True,
              help="Standard output: the summary and top-N table (text), the top-N rows as CSV, or a JSON "
                   "document (counts, top-N rows, files written). Messages go to stderr with csv/json.")
@click.option("--exclude-asymmetric", is_flag=True,
              help="Leave unranked the designs whose harmonic check (sweep with solver: {harmonics: N}) "
                   "found a non-axisymmetric mode losing stability before V*; without it they are ranked "
                   "and the table's asym_n column names the harmonic.")
@click.option("--overwrite", is_flag=True,
              help="Replace an existing ranked file or plots (refused by default, as in every command).")
@verbosity_options
def command(results: Path, top: int, output: Path | None, plots_dir: Path | None, rho: float, c_d: float,
            alpha: float, fmt: str, exclude_asymmetric: bool, overwrite: bool) -> None:
    import pyarrow as pa

    from snapjump_cli.files import OutputLock, check_writable, follow_links, os_error_reason
    from snapjump_cli.sweep import results as res
    from snapjump_cli.jump import JumpParams

    try:
        params = JumpParams(rho=rho, c_d=c_d, alpha=alpha)
    except (ValueError, TypeError) as e:
        raise BadInput(f"jump parameters: {e}") from None
    try:  # the one reader of result files: a FIFO, a CSV, a column of the wrong kind, metadata not JSON
        df = res.read_results(results)
        meta = res.read_metadata(results)
    except res.ResultsFileError as e:
        raise BadInput(str(e)) from None
    except (pa.ArrowException, OSError) as e:
        raise BadInput(f"{results}: not a readable parquet file ({str(e).splitlines()[0]})") from None
    if "rank" in meta or "rank" in df.columns:
        src = (meta.get("rank") or {}).get("source") if isinstance(meta.get("rank"), dict) else None
        raise BadInput(f"{results}: is a ranked table (written by snapjump rank" + (f" from {src}" if src else "")
                       + "); give rank the results file of the sweep")
    out = output if output is not None else results.with_name(results.name.removesuffix(".parquet") + ".ranked.parquet")
    if out.suffix.lower() not in (".parquet", ".csv"):
        raise BadInput(f"-o/--output: {out}: expected a .parquet or .csv file name")
    if out.resolve() == results.resolve():
        raise BadInput(f"-o/--output: {out} would overwrite the input results file")
    # every output place is checked before anything is written
    check_writable(out, BadInput, overwrite=overwrite)
    target = follow_links(out)  # a link: the file it points to is written (its lock beside it)
    with ExitStack() as held:  # the output's lock, for the whole run: a second rank into it is refused
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            held.enter_context(OutputLock(target, command="rank", error=BadInput))
        except OSError as e:
            raise BadInput(f"{out}: cannot create its folder ({os_error_reason(e)})") from None
        check_writable(out, BadInput, overwrite=overwrite)  # again, under the lock: another run may have written it
        _rank_locked(results, df, meta, out, plots_dir, params, top, fmt, exclude_asymmetric, overwrite)


def _rank_locked(results: Path, df: Any, meta: dict, out: Path, plots_dir: Path | None, params: Any, top: int,
                 fmt: str, exclude_asymmetric: bool, overwrite: bool) -> None:
    """Rank, write and report, under the output's lock."""
    from snapjump_cli.files import AtomicFiles, check_writable
    from snapjump_cli.sweep import results as res
    from snapjump_cli.jump.rank import RankInputError, rank_results, settings_mix, top_frame, top_table

    if plots_dir is not None:
        from snapjump_cli.viz.figures import PLOT_FILES

        check_writable(plots_dir, BadInput, what="folder")
        for name in PLOT_FILES:
            check_writable(plots_dir / name, BadInput, overwrite=overwrite)
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise BadInput("--plots needs matplotlib, which is not installed (pip install 'snapjump[plots]')") from None
    try:
        ranked = rank_results(df, params, exclude_asymmetric=exclude_asymmetric)
    except RankInputError as e:
        raise BadInput(f"{results}: {e}") from None
    if not is_quiet():
        for line in settings_mix(df):
            click.echo(f"warning: {results} mixes rows computed with different settings: {line}", err=True)
    meta = dict(meta)
    meta["rank"] = {
        "source": str(results),
        "jump_params": {k: getattr(params, k) for k in params.__dataclass_fields__},
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "n_rows": int(len(ranked)),
        "n_ranked": int(ranked["rank"].notna().sum()),
    }
    files = [out]
    with AtomicFiles() as written:  # the table and the plots, all or none
        if out.suffix.lower() == ".csv":
            written.add(out, lambda tmp: ranked.to_csv(tmp, index=False))
        else:
            written.add(out, lambda tmp: res.write_frame_atomic(ranked, tmp, meta))
        if plots_dir is not None:
            from snapjump_cli.viz.figures import make_plots

            files += make_plots(ranked, plots_dir, batch=written)

    counts = {str(k): int(v) for k, v in ranked["status"].value_counts().items()}
    n_jumped = int(ranked["jumped"].fillna(False).astype(bool).sum())
    say = (lambda line: click.echo(line, err=True)) if fmt != "text" else click.echo
    summary = (f"{results}: {len(ranked)} designs ({', '.join(f'{k} {v}' for k, v in sorted(counts.items()))}); "
               f"{n_jumped} jump")
    reasons = res.failure_reasons(ranked, source=results)
    if fmt == "text":
        click.echo(summary)
        if top > 0:
            click.echo(top_table(ranked, top))
    elif fmt == "csv":
        click.echo(top_frame(ranked, top).to_csv(index=False), nl=False)
    else:
        rows = json.loads(top_frame(ranked, top).to_json(orient="records"))
        click.echo(json.dumps({"source": str(results), "n_designs": int(len(ranked)), "status_counts": counts,
                               "n_jumped": n_jumped, "top": rows, "files": [str(f) for f in files],
                               "reasons": reasons}, indent=1))
    if not is_quiet():  # on stderr: stdout keeps the table (or the CSV / JSON) alone
        for line in reasons:
            click.echo(line, err=True)
    if not is_quiet():
        for f in files:
            say(f"wrote {f}")


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump rank`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["rank", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
