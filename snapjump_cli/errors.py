"""Errors shared by the library and the commands.

:class:`BadInput` turns bad input into a one-line message and exit code 2 (no traceback, nothing
written); the commands raise it from the library's input errors such as :class:`SweepInputError`.
"""
from __future__ import annotations

import click


class BadInput(click.UsageError):
    """Bad user input: printed as one line, exit code 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # one line, no usage block
        click.echo(f"Error: {self.format_message()}", err=True)


class SweepError(RuntimeError):
    """The sweep itself cannot proceed (not a single design's failure)."""


class SweepInputError(SweepError):
    """The sweep cannot start because of the user's input (output path, lock, settings, scheduler)."""
