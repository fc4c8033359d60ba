"""Benchmarks and the validation suites, in folders by what they check (``README.md`` lists them; run from the
repository root with PYTHONPATH=.)."""
