"""One-off profiles worth keeping: each module has ``main(argv=None)`` and a ``--help`` that the
test suite runs (``tests/unit/test_bench_tools.py``); none is run by a make target.

* :mod:`bench.profile.follow`: where a followed branch's CPU goes, per design.
"""
