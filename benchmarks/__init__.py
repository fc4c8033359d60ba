"""Benchmarks and the validation suites (run from the repository root with PYTHONPATH=.)."""
