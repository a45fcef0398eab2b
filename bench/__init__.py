"""Benchmarks of snapjump (see ``bench/README.md``).

What a make target or a test runs: :mod:`bench.regression` (``make bench``: throughput and
answers against the committed baseline), :mod:`bench.tables` (``make scenes-table``,
``named-jumps``, ``harmonics-counts``), :mod:`bench.run_bench` with :mod:`bench.cases`,
:mod:`bench.runner`, :mod:`bench.analysis`, :mod:`bench.timings` and :mod:`bench.mesh_report`
(``make bench-mesh``: error against run time per mesh setting), :mod:`bench.followed_fig4` and
:mod:`bench.grid_compare` (tools for finished runs), and the profiles in :mod:`bench.profile`.
"""
