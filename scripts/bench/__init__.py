"""scripts/benchmark's package: what runs (plan, experiments), how (runner), how loops are scored
against GT (scoring), the plots and the Markdown of docs/BENCHMARKS.md. scripts/benchmark.py is
its command line."""
