"""sicomat.budget: the memory estimate made before large arrays, in the library (not only the CLI)."""

from __future__ import annotations

from pathlib import Path

import pytest

from sicomat.budget import DEFAULT_MAX_MEMORY, format_bytes, max_memory, require_memory
from sicomat.errors import ModelError, ResourceError, SicomatError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("text, expected", [("", DEFAULT_MAX_MEMORY), ("1000", 1000), ("8 GiB", 8 * 1024 ** 3),
                                            ("500MB", 500e6), ("1.5 kib", 1536), ("2e9", 2e9)])
def test_limit_from_the_environment(monkeypatch, text, expected):
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", text)
    assert max_memory() == expected


@pytest.mark.parametrize("text", ["lots", "-5 GiB", "0", "8 GiBs", "nan"])
def test_a_bad_limit_is_a_model_error_naming_the_variable(monkeypatch, text):
    monkeypatch.setenv("SICOMAT_MAX_MEMORY", text)
    with pytest.raises(ModelError, match="SICOMAT_MAX_MEMORY"):
        max_memory()


def test_require_memory_names_the_estimate_the_limit_and_the_variable(monkeypatch):
    monkeypatch.delenv("SICOMAT_MAX_MEMORY", raising=False)
    require_memory(DEFAULT_MAX_MEMORY, "this work")
    with pytest.raises(ResourceError) as info:
        require_memory(3 * 1024 ** 4, "this work", "many samples")
    message = str(info.value)
    assert "3 TiB" in message and "2 GiB" in message and "SICOMAT_MAX_MEMORY" in message
    assert isinstance(info.value, SicomatError) and isinstance(info.value, MemoryError)
    assert format_bytes(1536) == "1.5 KiB"


def test_the_python_api_is_protected_too(monkeypatch):
    monkeypatch.delenv("SICOMAT_MAX_MEMORY", raising=False)
    from sicomat import load_model
    from sicomat.servo.loop import build_servo_loop
    from sicomat.motion import Line, Path as ToolPath, interpolate
    from sicomat.motion.setpoints import step_profile
    from sicomat.simulation import simulate

    loop = build_servo_loop(load_model(EXAMPLES / "rigid_1m.toml"))
    with pytest.raises(ResourceError, match="this simulation needs about"):
        simulate(loop, step_profile(1e-3), 1e6)       # 8e9 steps of 125 us
    for duration in (float("nan"), float("inf"), -1.0):
        with pytest.raises(ModelError, match="duration"):
            simulate(loop, step_profile(1e-3), duration)
    with pytest.raises(ResourceError, match="this path interpolation"):
        interpolate(ToolPath([Line((0, 0), (1.0, 0))]), 1e-9, 1.0, 10.0, 1e-3)   # 1e9 s at 1 ms
