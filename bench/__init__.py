"""Benchmarks of snapjump: error against run time per mesh setting (``python -m bench.run_bench``).

See ``bench/README.md``. The modules: :mod:`bench.cases` (the scenes), :mod:`bench.runner` (one
timed solve in a forked, time-limited child), :mod:`bench.analysis` (references, errors, the
default), :mod:`bench.timings` (mesh, numba compile, CLI), :mod:`bench.report` (Markdown + plots).
"""
