"""TEST-ONLY: the real ``snapjump`` CLI with the fake ``slow_solve`` injected (for subprocess tests
that kill a sweep mid-run). Usage: ``python fake_sweep_main.py sweep GRID.yaml -o OUT ...``."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import snapjump_fake_solvers as fake  # noqa: E402

from snapjump_cli.cli import main  # noqa: E402

if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:], solve_fn=fake.slow_solve, warm_up_fn=fake.warm_up))
