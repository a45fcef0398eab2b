# snapjump — every target builds what it needs from scratch (a clean clone needs only Python >= 3.11).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install run run-followed test bench bench-mesh stress clean scenes-table named-jumps harmonics-counts

# install also checks, each time (~0.1 s, no numba), that the kernels compiled ahead of time for
# this CPU (fast start-up; docs/performance.md) were built from these kernel sources on this CPU:
# kernels/_aot_build.json records what they were built for; they are rebuilt otherwise. If the
# build fails the kernels run JIT-compiled, with the same answers (not retried until the sources
# or the CPU change; delete kernels/_aot_build.json to retry).
# the ahead-of-time build on one core, the followed branch's JIT kernels compiled on the other
install: $(STAMP)
	@$(BIN)/python -m snapjump_cli.fe.precompile --warm-followed & warm=$$!; \
	$(BIN)/python -m snapjump_cli.fe.precompile --if-stale; status=$$?; wait $$warm; exit $$status

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

run: install
	$(BIN)/snapjump -v sweep configs/paper_grid.yaml -o results/paper_grid.parquet
	$(BIN)/snapjump rank results/paper_grid.parquet -o results/ranked.parquet --plots results/ --overwrite

# the paper grid with every asymmetric-first design's branch followed (1 h 39 min on 2 cores, against 5 min 30 s for make run: docs/performance.md; resumable)
run-followed: install
	$(BIN)/snapjump -v sweep configs/paper_grid_followed.yaml -o results/paper_grid_followed.parquet
	$(BIN)/snapjump rank results/paper_grid_followed.parquet -o results/ranked_followed.parquet --plots results/followed/ --overwrite

test: install
	$(BIN)/python -m pytest -q -x --durations=15

# throughput and answers on the seeded paper-grid sample (-j 2), against bench/regression/baseline.json
bench: install
	$(BIN)/python -m bench.regression compare -j 2 --phase-sample 40 --report bench/out/THROUGHPUT.md --out bench/out/regression_rows.json $(BENCH_ARGS)

# the tables the docs quote (bench/tables.py): the paper's scenes at three mesh levels
# (~2 min), the named designs end to end (~10 s), the harmonic check over a sweep run with
# solver: {harmonics: 4} (RESULTS=..., default results/paper_grid_h4.parquet)
scenes-table: install
	$(BIN)/python -m bench.tables scenes $(TABLE_ARGS)

named-jumps: install
	$(BIN)/python -m bench.tables named-jumps $(TABLE_ARGS)

RESULTS ?= results/paper_grid_h4.parquet
harmonics-counts: install
	$(BIN)/python -m bench.tables harmonics $(RESULTS) $(TABLE_ARGS)

# run time against error per mesh setting (hours; resumable)
bench-mesh: install
	$(BIN)/python -m bench.run_bench $(BENCH_MESH_ARGS)

stress: install
	$(BIN)/python -m pytest -q -m stress tests/

clean:
	rm -rf $(VENV) build *.egg-info results bench/out .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
	find . -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -f kernels/_aot*.so kernels/_aot_build.json
