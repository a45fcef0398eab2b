"""snapjump: design snapping inflatable soft jumpers (axisymmetric Gent FE + Riks + jump model)."""
from __future__ import annotations

__version__ = "0.1.0"
