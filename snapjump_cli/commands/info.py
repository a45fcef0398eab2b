"""``snapjump info RESULTS.parquet``: what a result file holds, without pandas in your hands.

Prints the designs counted by status, the reasons of the invalid and failed designs grouped
(numbers in the messages masked, so one cause with many values is one group, with its count and
an example), whether the file is ranked (and its best jump), the sweep's config, the snapjump
version and commit, the Python and dependency versions, the host(s) and the time the file was
made (from the file's provenance metadata and the rows' own provenance columns). ``--format
json`` gives the same as one JSON object.

JSON keys (stable): ``file``, ``n_rows``, ``status_counts``, ``reasons`` (a list of ``status``,
``reason``, ``count``, ``example``), ``ranked``, ``best`` (null unless ranked), ``followed``
(rows whose branch was followed), ``command``, ``config``, ``version``, ``git``, ``python``,
``platform``, ``dependencies``, ``created_utc``, ``hosts``, ``finished_utc`` (first and last),
``settings_mix``.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Sequence

import click

from snapjump_cli.cli import verbosity_options
from snapjump_cli.errors import BadInput

__all__ = ["command", "main", "summarise"]

_ORDER = {"ok": 0, "no_snap": 1, "invalid_geometry": 2, "failed": 3}  # the order of sweep.rows.STATUSES


def summarise(path: Path) -> dict:
    """The summary of a result file (the JSON of ``--format json``)."""
    import pyarrow as pa

    from snapjump_cli.sweep import results as res

    try:
        df = res.read_results(path)
        meta = res.read_metadata(path)
    except res.ResultsFileError as e:  # the one reader's message: file, column or value, what to do
        raise BadInput(str(e)) from None
    except (pa.ArrowException, OSError) as e:
        raise BadInput(f"{path}: not a readable parquet file ({str(e).splitlines()[0]})") from None
    if "status" not in df.columns:
        raise BadInput(f"{path}: not a snapjump result file (no 'status' column)")
    status = df["status"].astype("string").fillna("(none)").tolist()
    errors = df["error"].tolist() if "error" in df.columns else [None] * len(df)
    counts: dict[str, int] = {}
    for s in status:
        counts[s] = counts.get(s, 0) + 1
    ranked = "rank" in df.columns and "y_jump_m" in df.columns
    best = None
    if ranked and df["y_jump_m"].notna().any():
        row = df.loc[df["y_jump_m"].astype("float64").idxmax()]
        best = {k: _plain(row[k]) for k in ("eta_i", "theta_i_deg", "eta_o", "theta_o_deg", "mu_ratio", "y_jump_m")
                if k in df.columns}
    followed = int(df["followed"].astype("boolean").fillna(False).sum()) if "followed" in df.columns else 0

    def col_values(c: str) -> list:
        return sorted({str(v) for v in df[c].dropna().tolist()}) if c in df.columns else []

    fin = sorted(col_values("finished_utc"))
    from snapjump_cli.jump.rank import settings_mix

    git = meta.get("git")
    return {
        "file": str(path),
        "n_rows": int(len(df)),
        "status_counts": dict(sorted(counts.items(), key=lambda kv: (_ORDER.get(kv[0], 9), kv[0]))),
        "reasons": res.group_failures(status, errors),
        "ranked": bool(ranked),
        "best": best,
        "followed": followed,
        "command": meta.get("command"),
        "config": meta.get("config"),
        "version": meta.get("version") or (col_values("snapjump_version") or [None])[0],
        "git": (git["commit"] + ("+dirty" if git.get("dirty") else "")) if isinstance(git, dict) and git.get("commit")
        else (col_values("git_commit") or [None])[0],
        "python": meta.get("python"),
        "platform": meta.get("platform"),
        "dependencies": meta.get("dependencies") or {},
        "created_utc": meta.get("created_utc"),
        "hosts": col_values("host"),
        "finished_utc": [fin[0], fin[-1]] if fin else [],
        "settings_mix": settings_mix(df),
    }


def _plain(v: Any) -> Any:
    try:
        import numpy as np

        if isinstance(v, np.generic):
            return v.item()
    except ImportError:  # pragma: no cover
        pass
    return None if v is None or (isinstance(v, float) and v != v) else v


def _text(s: dict) -> str:
    lines = [f"file             {s['file']}",
             f"designs          {s['n_rows']}: " + ", ".join(f"{k} {v}" for k, v in s["status_counts"].items())]
    if s["reasons"]:
        lines.append("why not solved   (numbers masked as #; count, then an example)")
        for g in s["reasons"]:
            lines.append(f"  {g['status']:<17}{g['count']:>6}  {g['reason']}")
            if g["example"] != g["reason"]:
                lines.append(f"  {'':<17}{'':>6}  e.g. {g['example']}")
    if s["followed"]:
        lines.append(f"followed         {s['followed']} design(s) answered by their followed branch")
    if s["ranked"]:
        b = s["best"]
        lines.append("ranked           yes" + (f"; best jump {b['y_jump_m'] * 1e3:.4g} mm: eta_i {b.get('eta_i')}, "
                                               f"theta_i {b.get('theta_i_deg')}, eta_o {b.get('eta_o')}, "
                                               f"theta_o {b.get('theta_o_deg')}, mu_ratio {b.get('mu_ratio')}"
                                               if b else ""))
    for line in s["settings_mix"]:
        lines.append(f"mixed settings   {line}")
    lines += [f"command          {s['command'] or '-'}",
              f"snapjump         {s['version'] or '-'}" + (f" (git {s['git']})" if s["git"] else ""),
              f"python           {s['python'] or '-'} on {s['platform'] or '-'}"]
    if s["dependencies"]:
        lines.append("dependencies     " + ", ".join(f"{k} {v}" for k, v in s["dependencies"].items()))
    lines.append(f"hosts            {', '.join(s['hosts']) or '-'}")
    lines.append(f"created          {s['created_utc'] or '-'}"
                 + (f"; rows finished {s['finished_utc'][0]} .. {s['finished_utc'][1]}" if s["finished_utc"] else ""))
    cfg = s["config"]
    if cfg:
        lines.append("config")
        for k, v in cfg.items():
            lines.append(f"  {k:<15}{json.dumps(v, default=str)}")
    return "\n".join(lines)


@click.command("info", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("results", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Output format.")
@verbosity_options
def command(results: Path, fmt: str) -> None:
    """Summarise a sweep's (or a ranked) result file: designs by status, why the invalid and
    failed ones were not solved (grouped), the config, versions, host and time.

    \b
    Examples:
      snapjump info results.parquet
      snapjump info results.ranked.parquet --format json
    """
    if not results.exists():
        raise BadInput(f"{results}: file not found")
    if not results.is_file():
        raise BadInput(f"{results}: expected a parquet file, got a {'directory' if results.is_dir() else 'special file'}")
    s = summarise(results)
    click.echo(json.dumps(s, indent=1, default=str) if fmt == "json" else _text(s))


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``snapjump info`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    from snapjump_cli.cli import main as cli_main

    return cli_main(["info", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
