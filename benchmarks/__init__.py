"""Speed figures for `make bench`: each ``bench_*.py`` module here has ``run() -> dict``.

``python -m benchmarks`` runs them all (or those named on the command line) and merges the
figures into ``results/bench.json``, keeping the keys of modules not run this time.
"""
