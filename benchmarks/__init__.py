"""SICOMAT's speed benchmarks: ours side by side with peers in the same run, reported as ratios.

Run them all with ``python -m benchmarks.run`` (``--quick`` for a smoke run); each module
``bench_*.py`` also runs alone (``python -m benchmarks.bench_simulation``) and has ``run() -> dict``.
Speed is measured here, never in the tests.
"""
