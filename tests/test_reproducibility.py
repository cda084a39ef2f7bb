"""The README's two commands are reproducible: a lock of tested versions, used by every install."""

from __future__ import annotations

import importlib
import os
import re
import shutil
import stat
import subprocess
import tomllib
from pathlib import Path

import pytest
from hypothesis import settings

ROOT = Path(__file__).resolve().parents[1]
LOCK = ROOT / "requirements.lock"
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([A-Za-z0-9.+!_-]+)$")


def _canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirement_name(requirement: str) -> str:
    return _canonical(re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", requirement).group(1))


def _pins() -> dict[str, str]:
    pins = {}
    for number, line in enumerate(LOCK.read_text().splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        match = PIN.match(line)
        assert match, f"requirements.lock:{number}: {line!r} is not an exact `name==version` pin"
        name = _canonical(match.group(1))
        assert name not in pins, f"requirements.lock:{number}: {name} pinned twice"
        pins[name] = match.group(2)
    return pins


def test_lock_pins_every_dependency_exactly():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    named = (pyproject["project"]["dependencies"] + pyproject["project"]["optional-dependencies"]["test"]
             + pyproject["build-system"]["requires"])
    pins = _pins()
    missing = sorted({_requirement_name(r) for r in named} - set(pins))
    assert not missing, f"requirements.lock does not pin {missing}; run `make lock`"
    assert "sicomat" not in pins, "the lock constrains dependencies, not the package itself"
    # transitive dependencies are pinned too (numba pulls llvmlite, pydantic pulls pydantic-core)
    assert {"llvmlite", "pydantic-core"} <= set(pins)
    assert LOCK.read_text().startswith("#") and "make lock" in LOCK.read_text().split("\n\n")[0]


def test_lock_versions_lie_in_pyproject_ranges():
    # A pin outside an open range would make `pip install -c requirements.lock` unsatisfiable.
    packaging_version = pytest.importorskip("packaging.version")
    pins = _pins()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    for requirement in pyproject["project"]["dependencies"] + pyproject["build-system"]["requires"]:
        match = re.fullmatch(r"([A-Za-z0-9._-]+)>=([0-9.]+)", requirement)
        if match:
            name = _canonical(match.group(1))
            assert packaging_version.Version(pins[name]) >= packaging_version.Version(match.group(2)), \
                (name, pins[name], requirement)


def test_library_users_keep_open_ranges():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    for requirement in pyproject["project"]["dependencies"]:
        assert "==" not in requirement, f"pyproject.toml pins {requirement}: pins belong in requirements.lock"


def test_makefile_installs_from_the_lock():
    makefile = (ROOT / "Makefile").read_text()
    stamp_rule = re.search(r"^\$\(STAMP\):(.*)$", makefile, re.M)
    assert stamp_rule and "$(LOCK)" in stamp_rule.group(1) and "pyproject.toml" in stamp_rule.group(1)
    assert re.search(r"^LOCK := requirements\.lock$", makefile, re.M)
    assert re.search(r"^export PIP_CONSTRAINT := ", makefile, re.M)
    assert re.search(r"^PIP_INSTALL := .*pip install .*-c \$\(LOCK\)", makefile, re.M)
    # every install into the project's venv goes through $(PIP_INSTALL), i.e. through the lock
    # (`make lock`'s own temporary venv, "$$tmp", is the one place that installs without it)
    direct = [line for line in makefile.splitlines()
              if "-m pip install" in line and not line.startswith("PIP_INSTALL :=") and "$$tmp" not in line]
    assert not direct, f"installs that bypass the lock: {direct}"
    assert re.search(r"\$\(PIP_INSTALL\) --build-constraint \$\(LOCK\) -e '\.\[test\]'", makefile)
    assert re.search(r"^lock:", makefile, re.M)


def test_license_is_an_spdx_expression_with_a_setuptools_that_reads_it():
    # setuptools >= 77 reads `license = "MIT"` (PEP 639); a table there is deprecated (a warning on install)
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["license"] == "MIT"
    assert "setuptools>=77" in pyproject["build-system"]["requires"]


def _default_profile(request):
    if request.config.getoption("hypothesis_profile", default=None) not in (None, "deterministic"):
        pytest.skip("another hypothesis profile was chosen on the command line")


def test_property_tests_are_deterministic(request):
    # the profile loaded by conftest.py: the same examples on every machine, no replay database
    _default_profile(request)
    assert settings.default.derandomize is True
    assert settings.default.database is None


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
@pytest.mark.parametrize("pytest_status, ci_fails", [(0, False), (1, True), (5, True)])
def test_ci_fails_when_tests_fail_or_none_ran(tmp_path, pytest_status, ci_fails):
    # .ci/run runs `make test` under `set -e`: a failing suite (1) and a suite that collected nothing (5)
    # both make CI fail. A stand-in venv whose python exits with the given status replaces pytest.
    (tmp_path / ".ci").mkdir()
    for name in ("Makefile", "pyproject.toml", "requirements.lock", ".ci/run"):
        shutil.copy(ROOT / name, tmp_path / name)
    bin_dir = tmp_path / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    python = bin_dir / "python"
    python.write_text(f"#!/bin/sh\nexit {pytest_status}\n")
    python.chmod(python.stat().st_mode | stat.S_IEXEC)
    stamp = tmp_path / ".venv" / ".installed"
    stamp.touch()
    future = os.stat(tmp_path / "Makefile").st_mtime + 10
    os.utime(stamp, (future, future))  # the stand-in venv is up to date: make does not reinstall
    result = subprocess.run(["bash", ".ci/run"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert (result.returncode != 0) == ci_fails, result.stdout + result.stderr


@pytest.mark.parametrize("module", ["test_margins", "test_mechanics", "test_reduction", "test_trajectory"])
def test_every_property_test_draws_the_same_examples_everywhere(module, request):
    # each @given test's own @settings inherit the profile: derandomized, no replay database
    _default_profile(request)
    tests = [f for f in vars(importlib.import_module(module)).values() if hasattr(f, "hypothesis")]
    assert tests, f"{module} has no property test any more: update this list"
    for test in tests:
        chosen = test._hypothesis_internal_use_settings
        assert chosen.derandomize is True and chosen.database is None, test.__name__
