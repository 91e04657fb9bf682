"""scripts/benchmark's package: what runs (plan, experiments), how (runner), how loops are scored
against GT (scoring: `sparseloop eval`), the plots and the Markdown of docs/BENCHMARKS.md (markdown:
numbers and tables; the prose is the template BENCHMARKS.md.in). scripts/benchmark.py is its
command line."""
