"""A clean stop on Ctrl-C or SIGTERM, shared by the long-running commands (``sweep``, ``optimize``)."""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any, Iterator

import click

__all__ = ["Interrupted", "sigterm_as_interrupt"]


class Interrupted(click.ClickException):
    """Ctrl-C / SIGTERM: one line, exit code 130."""

    exit_code = 130

    def show(self, file: Any = None) -> None:
        """Print the message alone (no ``Error:`` prefix) on stderr."""
        click.echo(self.format_message(), err=True)


@contextmanager
def sigterm_as_interrupt(message: str) -> Iterator[None]:
    """Treat SIGTERM like Ctrl-C inside the block, and turn either into :class:`Interrupted`.

    Parameters
    ----------
    message
        The one line printed on stderr when the block is interrupted (say what was kept).

    Raises
    ------
    Interrupted
        The block raised :class:`KeyboardInterrupt` (Ctrl-C, or SIGTERM in the main thread).

    Notes
    -----
    The SIGTERM handler is installed only in the main thread (Python allows no other) and the
    previous handler is restored on leaving the block.
    """
    restore = None
    if threading.current_thread() is threading.main_thread():
        def _on_term(signum: int, frame: Any) -> None:  # SIGTERM -> same clean stop as Ctrl-C
            raise KeyboardInterrupt

        restore = signal.signal(signal.SIGTERM, _on_term)
    try:
        yield
    except KeyboardInterrupt:
        raise Interrupted(message) from None
    finally:
        if restore is not None:
            signal.signal(signal.SIGTERM, restore)
