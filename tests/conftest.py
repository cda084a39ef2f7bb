"""Test-session setup: a headless matplotlib backend and deterministic property tests."""

from __future__ import annotations

import matplotlib
from hypothesis import settings

matplotlib.use("Agg")

# Property tests draw the same examples on every machine and every run (docs/conventions.md, "Tests
# and tolerances"): derandomize seeds each test's search from the test itself, and without an example
# database a failure found on one machine is not replayed there only. A fresh clone therefore cannot
# draw a new, never-seen failing example; widening the search is a deliberate edit of max_examples.
# `--hypothesis-profile=explore` searches randomly (with a local database) for a developer hunting bugs.
settings.register_profile("deterministic", derandomize=True, database=None, print_blob=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile("deterministic")
