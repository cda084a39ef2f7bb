"""The coupled loops of a ``[robot]`` machine for ``sicomat margins|bode|simulate|tune --coupled``: one loop
with the others closed beside the same loop on its decoupled model (the other motors locked), and a move of
one axis while the others hold their position, all on the coupled model
(:func:`~sicomat.servo.coupled.robot_coupled_loop`). Errors name the parameter (``which``, ``trajectory``) or the model's
``robot`` section."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..errors import ModelError

if TYPE_CHECKING:  # pragma: no cover
    from ..frequency.margins import Margins
    from ..lti.response import FrequencyResponse
    from ..servo.coupled import CoupledLoop
    from ..servo.loop import ServoLoop
    from ..simulation.coupled import CoupledRun

__all__ = ["coupled_loops", "CoupledMargins", "coupled_margins", "coupled_bode", "coupled_tuning_check",
           "simulate_coupled_move"]


def coupled_loops(machine) -> "CoupledLoop":
    """Every motorised joint's loop of a ``[robot]`` machine on its coupled model; a
    :class:`~sicomat.errors.ModelError` (at ``robot``) for a machine without one."""
    if machine.robot is None:
        raise ModelError("coupled loops are the loops of a [robot] machine's motorised joints on its coupled model; "
                         "this model has no [robot] section (its axes are independent: leave out --coupled)",
                         path="robot")
    from ..servo.coupled import robot_coupled_loop

    return robot_coupled_loop(machine)


def _notes(coupled: "CoupledLoop", axis: str) -> list[str]:
    """The sentences that say what the analysis of ``axis`` closes of the other axes."""
    from ..servo.coupled_linear import closed_partners

    closed = closed_partners(coupled, axis)
    held = [name.split(".")[0] for name in closed["velocity"]["open"]]
    if not held:
        return []
    periods = ", ".join(f"{name} {coupled.loop(name).controller.position_period:g} s" for name in held)
    return [f"velocity loop of {axis}: the position loops of {', '.join(held)} are open (their velocity commands "
            f"held), as {axis}'s own: they sample at their position period ({periods}), not at the velocity "
            f"period {coupled.base_period:g} s, and closed they would make the loop periodic, with no exact "
            f"frequency response; the position loop of {axis} has them closed"]


class CoupledMargins:
    """The margins of one axis's loops with the other axes closed and on its decoupled model: ``payload``
    (the ``margins --coupled --json`` object), ``coupled`` and ``decoupled`` (``{"velocity": Margins,
    "position": Margins}``)."""

    def __init__(self, payload: dict[str, Any], coupled: dict[str, "Margins"], decoupled: dict[str, "Margins"]):
        self.payload, self.coupled, self.decoupled = payload, coupled, decoupled


def coupled_margins(machine, axis: str | None) -> CoupledMargins:
    """``sicomat margins --coupled``: today's margins object of the axis with the other loops closed, with
    ``"coupled": true``, ``"closed_loops"`` (what the analysis closes of the other axes), ``"notes"``,
    and ``"decoupled"``: the same object on the axis's decoupled model (``sicomat margins`` without
    ``--coupled``)."""
    from ..frequency.coupled import closed_partners, coupled_analysis
    from ..frequency.loops import LoopAnalysis
    from ..frequency.margins import stability_margins
    from .analysis import margins_payload

    coupled = coupled_loops(machine)
    name = machine.axis_name(axis)
    an = coupled_analysis(coupled, name)
    servo = an.loop
    alone = LoopAnalysis.of(servo)
    both = {label: {which: stability_margins(analysis.response(f"{which}-open")) for which in ("velocity", "position")}
            for label, analysis in (("coupled", an), ("decoupled", alone))}
    decoupled = margins_payload(servo, alone, both["decoupled"]["velocity"], both["decoupled"]["position"])
    payload = {"axis": name, **margins_payload(servo, an, both["coupled"]["velocity"], both["coupled"]["position"]),
               "coupled": True, "closed_loops": closed_partners(coupled, name), "notes": _notes(coupled, name),
               "decoupled": {"axis": name, **decoupled}}
    return CoupledMargins(payload, both["coupled"], both["decoupled"])


def coupled_bode(machine, axis: str | None, which: str, points: int
                 ) -> tuple[dict[str, Any], "FrequencyResponse", "Margins | None", "FrequencyResponse", "Margins | None"]:
    """``sicomat bode --coupled``: the transfer ``which`` of the axis with the other loops closed and on its
    decoupled model. Returns the payload (today's bode object with ``"coupled": true``, ``"closed_loops"``,
    ``"notes"`` and ``"decoupled"``: the same object on the decoupled model), then the coupled response and
    margins (for an open loop), the decoupled ones."""
    from ..frequency.coupled import COUPLED_LOOPS, closed_partners, coupled_analysis, coupled_omega
    from ..frequency.loops import LoopAnalysis, default_omega
    from ..frequency.margins import stability_margins
    from .analysis import bode_payload, response_verdict

    if which not in COUPLED_LOOPS:
        raise ModelError(f"with the other loops closed, expected one of {', '.join(COUPLED_LOOPS)} (the plant, the "
                         "compliance and the disturbance response are one axis's mechanics: leave out --coupled)",
                         path="which", value=which)
    coupled = coupled_loops(machine)
    name = machine.axis_name(axis)
    an = coupled_analysis(coupled, name)
    servo = an.loop
    decoupled = LoopAnalysis.of(servo)
    out = []
    for analysis, omega in ((an, coupled_omega(an, which, points)), (decoupled, default_omega(servo, which, points))):
        frf = analysis.response(which, omega)
        margins = stability_margins(frf) if frf.open_loop else None
        verdict = response_verdict(servo, analysis, which, margins)
        out.append((frf, margins, {**bode_payload(frf, margins), **verdict.to_dict()}))
    payload = {**out[0][2], "coupled": True, "closed_loops": closed_partners(coupled, name),
               "notes": _notes(coupled, name), "decoupled": out[1][2]}
    return payload, out[0][0], out[0][1], out[1][0], out[1][1]


def coupled_tuning_check(machine, tuned: "ServoLoop", targets) -> tuple[dict[str, Any], dict[str, "Margins"]]:
    """The tuned loop of axis ``tuned.axis`` (tuned on its decoupled model) with the other loops of the robot
    closed: the ``"coupled_margins"`` object of ``sicomat tune`` — the margins as ``margins --coupled``
    reports them, the poles' verdict, ``"closed_loops"``, and ``"targets_met"``/``"unmet"``: whether the
    tuning's targets still hold coupled (``targets`` a resolved :class:`~sicomat.tuning.frequency.TuningTargets`:
    the frequency approach's targets and tolerances, ``"achieved"`` as the tuning reports it; or a
    :class:`~sicomat.tuning.time.TimeTargets`: the margin floors of the time approach — its step overshoots
    are the decoupled model's). Also the coupled margins (for the table)."""
    from ..frequency.coupled import closed_partners, coupled_analysis, coupled_omega
    from ..frequency.margins import stability_margins
    from ..servo.coupled import CoupledLoop
    from ..servo.stability import loop_verdict
    from ..tuning.frequency import Gains, TuningTargets, targets_on
    from ..tuning.time import margin_check

    base = coupled_loops(machine)
    loops = tuple(tuned if loop.axis == tuned.axis else loop for loop in base.loops)
    coupled = CoupledLoop(base.mechanics, loops, base.tools)
    an = coupled_analysis(coupled, tuned.axis)
    margins = {which: stability_margins(an.response(f"{which}-open")) for which in ("velocity", "position")}
    verdict = loop_verdict(tuned, an=an)
    out: dict[str, Any] = {which: {**m.to_dict(), "stable": verdict.loops.get(which)} for which, m in margins.items()}
    if isinstance(targets, TuningTargets):
        achieved, unmet = targets_on(an, targets, Gains(tuned.Kp, tuned.Kp_normalized, tuned.Ti, tuned.Kv),
                                     grid=lambda loop, which, n: coupled_omega(an, which, n))
        out["achieved"] = {key: getattr(achieved, key) for key in achieved.__dataclass_fields__}
    else:
        _, unmet = margin_check(an, tuned.Kp, tuned.Ti, tuned.Kv, targets)
    unmet += list(verdict.warnings)
    out.update({"targets_met": not unmet, "unmet": unmet, "closed_loops": closed_partners(coupled, tuned.axis),
                "notes": _notes(coupled, tuned.axis), **verdict.to_dict()})
    return out, margins


def simulate_coupled_move(machine, axis: str | None, step_mm: float | None, move_mm: float | None,
                          max_velocity: float | None, max_acceleration: float | None, duration: float | None, *,
                          nonlinear: bool = True, progress=None) -> tuple[dict[str, Any], "CoupledRun | None"]:
    """``sicomat simulate --coupled``: the axis follows a step, a move or its trajectory while every other axis
    holds its position (a constant setpoint), all on the coupled model. Returns today's simulate object of the
    moving axis with ``"coupled": true`` and ``"axes"`` (each axis's figures: following errors, step
    figures), the verdict of the coupled loops; and the run (None when it diverged)."""
    from ..motion.setpoints import step_profile
    from ..simulation.checks import coupled_simulation_verdict, diverged_verdict
    from ..simulation.coupled import simulate_coupled
    from ..simulation.kernel import SimulationDiverged
    from ..simulation.timeseries import StepMetrics
    from .simulate import STEP_FIGURES, choose_profile, diverged_payload, simulate_payload

    coupled = coupled_loops(machine)
    name = machine.axis_name(axis)
    trajectory = machine.axes[name].trajectory
    if step_mm is None and move_mm is None and trajectory is None:
        raise ModelError("no setpoint: give a step or a move, or add a [axes.<name>.trajectory] table",
                         path="trajectory")
    profile, default_duration = choose_profile(trajectory, step_mm, move_mm, max_velocity, max_acceleration)
    profiles = {other: profile if other == name else step_profile(0.0) for other in coupled.axes}
    try:
        run = simulate_coupled(coupled, profiles, duration if duration is not None else default_duration,
                               nonlinear=nonlinear, progress=progress)
    except SimulationDiverged as exc:
        from ..servo.coupled_linear import coupled_verdict
        from ..simulation import simulation_notes

        loop = coupled.loop(name)
        verdict = diverged_verdict(loop, exc, coupled_verdict(coupled))
        figures = {key: None for key in StepMetrics.__dataclass_fields__}
        payload = {**diverged_payload(loop, exc, verdict, simulation_notes(loop, nonlinear)), "coupled": True,
                   "axes": {other: dict(figures) for other in coupled.axes}}
        return payload, None
    verdict = coupled_simulation_verdict(coupled, run, profiles)
    axes = {}
    for other in coupled.axes:
        figures = run[other].metrics.to_dict()  # type: ignore[union-attr]
        if verdict.stable is False:             # an unstable loop's step figures mean nothing (as simulate's)
            figures.update({key: None for key in STEP_FIGURES})
        axes[other] = figures
    return {**simulate_payload(run[name], verdict), "coupled": True, "axes": axes}, run
