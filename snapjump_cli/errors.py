"""Turning bad input into a one-line message and exit code 2 (no traceback, nothing written)."""
from __future__ import annotations

import click


class BadInput(click.UsageError):
    """Bad user input: printed as one line, exit code 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # one line, no usage block
        click.echo(f"Error: {self.format_message()}", err=True)
