"""The ``snapjump`` command group. Each command lives in ``snapjump_cli/commands/<name>.py``
and is imported only when it is run (``snapjump --help`` stays fast).

Ctrl-C (or SIGTERM where a command asks for it) at any moment ends the command with exit code 130
and one line, ``interrupted``: while this module is imported by the ``snapjump`` program, a SIGINT
ends the process at once with that line (nothing has been written yet); from :func:`main` on, it is
Python's ``KeyboardInterrupt``, which the commands turn into a clean stop.
"""
from __future__ import annotations

import os
import signal
import sys
import threading

#: The one line of an interrupted command, and its exit code.
INTERRUPTED, EXIT_INTERRUPTED = "interrupted", 130


def _interrupted_at_start(signum: int, frame: object) -> None:  # pragma: no cover - timing dependent
    os.write(2, f"{INTERRUPTED}\n".encode())
    os._exit(EXIT_INTERRUPTED)


def _is_program() -> bool:
    """Whether this process is the ``snapjump`` program (not a library user importing the CLI)."""
    arg0 = sys.argv[0] if sys.argv and sys.argv[0] else ""
    name = os.path.basename(arg0)
    return name == "snapjump" or (name == "__main__.py" and os.path.basename(os.path.dirname(arg0)) == "snapjump_cli")


if _is_program() and threading.current_thread() is threading.main_thread() \
        and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _interrupted_at_start)  # Ctrl-C during the imports below: one line, 130

import importlib  # noqa: E402
import logging  # noqa: E402
from typing import Any, Sequence  # noqa: E402

import click  # noqa: E402

from snapjump_cli import __version__

COMMANDS = {
    "mesh": "Build and mesh one scene (design or single cap); print its geometry.",
    "curve": "Trace one scene's pressure-volume path and report its snap metrics.",
    "sweep": "Solve a YAML grid of designs in parallel into a parquet file (resumable).",
    "rank": "Apply the jump model to sweep results and rank the designs by jump height.",
    "optimize": "Search the continuous design space for the highest jump, then confirm it (resumable).",
    "info": "Summarise a result file: designs by status, why some were not solved, config, versions.",
    "report": "Write a self-contained HTML page for one design or for a result file.",
}


class LazyGroup(click.Group):
    """A click group whose sub-commands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in COMMANDS:
            return None
        mod = importlib.import_module(f"snapjump_cli.commands.{name}")
        return mod.command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Commands"):
            formatter.write_dl(sorted(COMMANDS.items()))


def set_verbosity(ctx: click.Context, verbose: int = 0, quiet: bool = False) -> None:
    """Set the log level of the ``snapjump_cli`` loggers (the only place that does) and remember
    ``quiet`` in ``ctx.obj`` for the commands: WARNING by default, INFO with -v, DEBUG with -vv,
    ERROR with -q (which also hides progress output). Given before or after the sub-command."""
    obj = ctx.ensure_object(dict)
    obj["verbose"] = obj.get("verbose", 0) + int(verbose or 0)
    obj["quiet"] = obj.get("quiet", False) or bool(quiet)
    v = obj["verbose"]
    level = logging.ERROR if obj["quiet"] else logging.DEBUG if v >= 2 else logging.INFO if v == 1 else logging.WARNING
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    logging.getLogger("snapjump_cli").setLevel(level)


def _verbose_cb(ctx: click.Context, param: click.Parameter, value: int) -> None:
    if value:
        set_verbosity(ctx, verbose=value)


def _quiet_cb(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if value:
        set_verbosity(ctx, quiet=True)


def verbosity_options(f):
    """``-v/--verbose`` and ``-q/--quiet`` on a sub-command too (``snapjump sweep -v ...``)."""
    f = click.option("-q", "--quiet", is_flag=True, expose_value=False, callback=_quiet_cb,
                     help="Only errors; no progress output.")(f)
    f = click.option("-v", "--verbose", count=True, expose_value=False, callback=_verbose_cb,
                     help="More log output (-v info, -vv debug).")(f)
    return f


def is_quiet() -> bool:
    """Whether -q was given (before or after the sub-command)."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx and ctx.find_root().obj and ctx.find_root().obj.get("quiet"))


def injected(name: str):
    """An object injected by the caller of :func:`main` (e.g. ``solve_fn`` in tests), or None."""
    ctx = click.get_current_context(silent=True)
    obj = ctx.find_root().obj if ctx else None
    return (obj or {}).get(name)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="snapjump")
@click.option("-v", "--verbose", count=True, help="More log output (-v info, -vv debug).")
@click.option("-q", "--quiet", is_flag=True, help="Only errors; no progress output.")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: bool) -> None:
    """snapjump: design snapping inflatable soft jumpers.

    Axisymmetric incompressible-Gent FE of two spherical caps inflated under volume control,
    traced with arc-length continuation through its limit points (Gorissen et al., Sci. Robot.
    2020), and a mass-spring model that turns the snap into a jump height.
    """
    set_verbosity(ctx, verbose, quiet)


def main(argv: Sequence[str] | None = None, **inject: Any) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 failure, 2 bad input, including an output that
    cannot be written: a full disk, an I/O error).

    ``inject`` passes Python objects to the commands (tests and notebooks), e.g.
    ``main(["sweep", ...], solve_fn=my_solver, warm_up_fn=None)``.
    """
    if signal.getsignal(signal.SIGINT) is _interrupted_at_start:  # from here on, Ctrl-C stops cleanly
        signal.signal(signal.SIGINT, signal.default_int_handler)
    for stream in (sys.stdout, sys.stderr):  # a file name that is not valid UTF-8 is shown, never a traceback
        if getattr(stream, "errors", None) == "strict" and hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # pragma: no cover - a stream that cannot change
                pass
    try:
        rc = cli.main(args=list(argv) if argv is not None else None, prog_name="snapjump", standalone_mode=False,
                      obj=dict(inject))
        if isinstance(rc, int):  # ctx.exit(n) under standalone_mode=False returns n
            return rc
    except click.exceptions.Exit as e:
        return int(e.exit_code or 0)
    except click.ClickException as e:  # UsageError, BadParameter, ... -> exit 2 (one line, no traceback)
        e.show()
        return 2 if e.exit_code in (1, 2) and isinstance(e, (click.UsageError, click.BadParameter)) else e.exit_code
    except (click.exceptions.Abort, KeyboardInterrupt):  # Ctrl-C (click turns it into Abort): one line, 130
        click.echo(INTERRUPTED, err=True)
        return EXIT_INTERRUPTED
    except OSError as e:  # a full disk, an I/O error, an output that may not be written: one line, exit 2
        from snapjump_cli.files import describe_os_error

        click.echo(f"Error: {describe_os_error(e)}", err=True)
        return 2
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
