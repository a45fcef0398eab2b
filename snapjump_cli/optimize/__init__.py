"""``snapjump optimize``: the design that jumps highest, by a search over the five design
parameters through the sweep's executor. Import it from here.

Modules: :mod:`.spec` (the SPEC.yaml schema and its validation, ``--from``, the cache paths),
:mod:`.evaluate` (batches of designs solved by ``run_sweep`` into the evaluation cache, their
objective, the confirmation on the finer mesh), :mod:`.search` (the normalised box, the
multi-start pattern search, differential evolution), :mod:`.plots` and :mod:`.run`
(``run_optimize``, ``OptimizeResult``, ``write_result``).
"""
from __future__ import annotations

from snapjump_cli.optimize.plots import make_plots, plot_files, plot_path, plot_progress
from snapjump_cli.optimize.run import SAME_SEARCH, OptimizeResult, check_output, run_optimize, write_result
from snapjump_cli.optimize.spec import (
    COLUMNS,
    IMPROVE_REL,
    METHODS,
    OBJECTIVES,
    PARAMETERS,
    POLLS,
    STAGES,
    ConfirmSettings,
    OptimizeInputError,
    OptimizeSpec,
    SearchSettings,
    cache_paths,
    check_cache,
    finer_mesh,
    load_spec,
    parse_spec,
    read_from,
)

__all__ = ["PARAMETERS", "OBJECTIVES", "METHODS", "STAGES", "POLLS", "COLUMNS", "IMPROVE_REL", "OptimizeSpec",
           "SearchSettings", "ConfirmSettings", "OptimizeResult", "OptimizeInputError", "load_spec", "parse_spec",
           "finer_mesh", "read_from", "run_optimize", "cache_paths", "check_cache", "write_result",
           "plot_progress", "plot_path", "make_plots", "plot_files", "check_output", "SAME_SEARCH"]
