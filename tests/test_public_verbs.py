"""The pipeline's verbs at the top of the package: `sicomat.reduce` (one entry point for every
reduction method) and `sicomat.loop_response` (the response of a named loop), and that the
library's errors name parameters, the command line options."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

import sicomat
from sicomat.cli.main import app

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
P5M4S = EXAMPLES / "paper_5m4s.toml"


@pytest.fixture(scope="module")
def machine():
    return sicomat.load_model(P5M4S)


@pytest.mark.parametrize("method, order", [("modal", 4), ("balanced", 5), ("balanced-dc", 6), ("schur", 6),
                                           ("hankel", 6)])
def test_reduce_is_the_method_it_names(machine, method, order):
    # the one entry point runs the same reductor on the same transfer (motor → scale, the default):
    # the same operations, so the same numbers (equal to round-off: 1e-12 relative).
    from sicomat.reduction import balanced as bal
    from sicomat.reduction.modal import modal_truncation

    plant = sicomat.build_mechanics(machine.axis().mechanics).state_space()
    io = {"inputs": ["motor"], "outputs": ["scale"]}
    direct = {"modal": lambda: modal_truncation(plant, order, **io),
              "balanced": lambda: bal.balanced_truncation(plant, order, **io),
              "balanced-dc": lambda: bal.balanced_truncation(plant, order, match_dc=True, **io),
              "schur": lambda: bal.schur_truncation(plant, order, **io),
              "hankel": lambda: bal.hankel_norm_approximation(plant, order, **io)}[method]()
    result = sicomat.reduce(machine, method, order=order)
    assert isinstance(result, sicomat.ReductionResult)
    assert result.order_after == direct.order_after == order
    assert_allclose(result.hinf_error, direct.hinf_error, rtol=1e-12)
    assert result.full.inputs == ("motor",) and result.full.outputs == ("scale",)


def test_reduce_takes_a_plant_too(machine):
    plant = sicomat.build_mechanics(machine.axis().mechanics).state_space()
    from_plant = sicomat.reduce(plant, "balanced", order=4, inputs="motor", outputs="scale")
    from_machine = sicomat.reduce(machine, "balanced", order=4)
    assert_allclose(from_plant.hinf_error, from_machine.hinf_error, rtol=1e-12)   # same operations
    with pytest.raises(sicomat.ModelError) as info:
        sicomat.reduce(plant, "physical", keep=["primary", "load"])
    assert info.value.path == "method"


def test_reduce_physical_regroups_the_machine(machine):
    result = sicomat.reduce(machine, "physical", keep="primary,load")
    assert result.machine is not None and set(result.spec.bodies) == {"primary", "load"}
    assert result.order_after == 4


@pytest.mark.parametrize("kwargs, parameter", [
    (dict(method="fourier"), "method"), (dict(order=0), "order"), (dict(band=(200.0, 100.0)), "band"),
    (dict(keep=["primary"]), "keep"), (dict(order=4, outputs="ghost"), "outputs"),
])
def test_reduce_errors_name_the_parameter(machine, kwargs, parameter):
    with pytest.raises(sicomat.ModelError) as info:
        sicomat.reduce(machine, **{"method": "modal", **kwargs})
    assert info.value.source is None and info.value.path == parameter and "--" not in str(info.value)


def test_loop_response_is_the_named_loop(machine):
    # the verb is the analysis's response of that transfer (the same computation): equal values
    loop = sicomat.build_servo_loop(machine)
    frf = sicomat.loop_response(loop, "position-open")
    assert isinstance(frf, sicomat.FrequencyResponse) and frf.open_loop
    same = sicomat.LoopAnalysis.of(loop).response("position-open")
    assert_allclose(frf.response, same.response, rtol=1e-12)
    omega = np.array([1.0, 10.0, 100.0])
    assert_allclose(sicomat.loop_response(loop, "velocity-closed", omega).omega, omega)


def test_loop_response_unknown_loop_names_the_parameter_and_the_cli_its_option(machine):
    loop = sicomat.build_servo_loop(machine)
    with pytest.raises(sicomat.ModelError) as info:
        sicomat.loop_response(loop, "sideways")
    assert info.value.path == "which" and "--" not in str(info.value)
    result = CliRunner().invoke(app, ["bode", str(P5M4S), "--loop", "sideways"])
    assert result.exit_code == 2 and result.stderr.startswith("error: --loop: unknown loop 'sideways'")


def test_simulate_option_checks_keep_their_messages():
    runner = CliRunner()
    both = runner.invoke(app, ["simulate", str(P5M4S), "--step", "1", "--move", "2"])
    assert both.exit_code == 2 and "give either --step or --move, not both" in both.stderr
    gcode = runner.invoke(app, ["simulate", str(EXAMPLES / "xy_table.toml"), "--gcode", str(EXAMPLES / "contour.nc"),
                                "--step", "1"])
    assert gcode.exit_code == 2 and "--gcode cannot be combined with --step or --move" in gcode.stderr


def test_every_exported_name_resolves():
    # sicomat.__getattr__ imports each name from the subpackage _EXPORTS names: every one must exist
    # (StepMetrics, simulate_path, circle_test, PathRun and CircleTest did not, after the re-layout)
    missing = [name for name in sicomat._EXPORTS if not hasattr(sicomat, name)]
    assert missing == []


def test_the_robotics_and_catalogue_subpackages_are_reached_from_import_sicomat():
    # the spelling, sicomat.robotics.MDHRobot.from_table, after a plain `import sicomat` (run in a
    # fresh interpreter: this test process may have imported the subpackages already)
    import subprocess
    import sys

    code = ("import sicomat, sys; assert 'sicomat.robotics' not in sys.modules; "
            "r = sicomat.robotics.MDHRobot.from_table([{'ant': 0, 'sigma': 1, 'M': 2.0}]); "
            "print(len(sicomat.catalogue.load_catalogue()) > 60, r.inverse_dynamics([0.0], [0.0], [1.0])[0])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    # a 2 kg prismatic link along the base z axis, gravity -9.81 along z: tau = M (qdd + 9.81) = 21.62 N
    assert out[0] == "True" and abs(float(out[1]) - 2.0 * (1.0 + 9.81)) < 1e-12
