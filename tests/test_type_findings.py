"""Real bugs the static type check (mypy, tests/test_architecture.py::test_mypy_clean) found, each
pinned by a test that failed before its fix. (The sensor whose ``body`` is not a name is in
tests/test_modelfile.py's ERROR_CASES; a top-level name that did not resolve in test_architecture.py.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from sicomat import ModelError, load_model

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_write_reduced_refuses_a_result_without_a_machine(tmp_path):
    # only the physical method gives a machine; a modal result used to reach save_model(None) and fail
    # with an AttributeError deep inside it (the CLI checks --write first, a Python caller did not)
    from sicomat.tasks.reduce import reduce_command, write_reduced

    result = reduce_command(load_model(EXAMPLES / "paper_5m4s.toml"), None, "modal", 4, None, None)
    assert result.machine is None
    target = tmp_path / "reduced.toml"
    with pytest.raises(ModelError, match="only the physical method gives a model file"):
        write_reduced(result, target)
    assert not target.exists()


def test_rigid_position_gain_needs_a_phase_margin_or_a_crossover():
    # with neither, the phase target was `-π + None · (π/180)`: a TypeError
    from sicomat.tuning.frequency import rigid_position_gain

    with pytest.raises(ValueError, match="phase_margin_deg or crossover"):
        rigid_position_gain(10.0, 1000.0, 0.01, 1e-4, 1e-3)


def test_a_diverged_axis_error_names_its_axis():
    # SimulationDiverged.axis was set on the instance after construction (not an attribute of the
    # class); it is now a keyword of the constructor and None by default
    from sicomat.simulation.kernel import SimulationDiverged

    assert SimulationDiverged("x", time=0.1, step=3).axis is None
    assert SimulationDiverged("x", time=0.1, step=3, axis="X").axis == "X"
