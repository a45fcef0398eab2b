"""Many designs into one result file: :mod:`.checks` (the one-line ``ConfigError`` and the
checking context of YAML inputs), :mod:`.config` (the sweep YAML), :mod:`.rows` (the row
contract), :mod:`.storage` (design keys, part files, the lock, consolidation), :mod:`.execution`
(joblib or dask workers), :mod:`.results` (parquet tables with provenance) and :mod:`.run`
(``run_sweep``, the orchestration)."""
