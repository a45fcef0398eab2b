"""Self-contained HTML pages: a design card (one solved scene) and a sweep report (a result file).

Every page is one file that needs nothing at view time: the figures are embedded as base64 PNG
(``data:`` URIs), the style is inline, and the only script (sorting the ranking's columns by a
click on their header) is a few lines of plain JavaScript in the page; no network, no library.
:func:`design_page` and :func:`results_page` return the HTML text
(:mod:`snapjump_cli.report.pages`).
"""
from __future__ import annotations

from snapjump_cli.report.pages import design_page, figure_png, results_page

__all__ = ["design_page", "results_page", "figure_png"]
