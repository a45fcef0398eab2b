"""Stress-suite fixtures: ``stresslib`` on sys.path and a terminal summary of what each stress test
found (counts by status, failure causes), also written to ``<SNAPJUMP_STRESS_DIR>/*.summary.md``."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

_SUMMARIES: list[str] = []


@pytest.fixture
def stress_report():
    """Call with a Markdown block: printed in the terminal summary of the session."""
    return _SUMMARIES.append


def pytest_terminal_summary(terminalreporter):
    if _SUMMARIES:
        terminalreporter.section("snapjump stress summary")
        for s in _SUMMARIES:
            terminalreporter.write_line(s)
