"""Entry point of the ``sicomat`` program; each command delegates to the library."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ._common import (AxisOption, FeedOption, JsonOption, MaxAccelerationOption, MaxVelocityOption, OneLineErrors, PlotOption,
                      SetOption, emit_json, exit_for, guarded, load, magnification_option, number)
from .progress import progress_bar

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, cls=OneLineErrors,
                  help="SICOMAT: simulation and control analysis of machine-tool feed axes.")

from .catalog import catalog_app  # noqa: E402  (the command group lives in its module)

app.add_typer(catalog_app, name="catalog")

from .robot import robot as _robot  # noqa: E402

app.command(name="robot")(_robot)

from .study import study as _study  # noqa: E402

app.command(name="study")(_study)

ModelArgument = typer.Argument(..., help="Model file (TOML).", dir_okay=False)


def _print_version(value: bool) -> None:
    if value:
        from .. import __version__

        typer.echo(f"sicomat {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: bool = typer.Option(False, "--version", is_eager=True, callback=_print_version,
                                       help="Print the version of sicomat and exit."),
          catalog: Optional[List[Path]] = typer.Option(
              None, "--catalog", metavar="DIR",
              help="A folder of catalogue entries that model files' part ids are looked up in, after the "
                   "shipped catalogue and SICOMAT_CATALOG (repeatable; put it before the command: "
                   "sicomat --catalog DIR modal MODEL).")) -> None:
    """SICOMAT: simulation and control analysis of machine-tool feed axes."""
    from ..catalogue.resolve import use_folders

    use_folders([str(c) for c in catalog or ()])


@app.command()
def check(model: Path = ModelArgument, set_: Optional[List[str]] = SetOption,
          lumped: bool = typer.Option(False, "--lumped",
                                      help="Show what each drive-chain axis (type = \"components\") is lowered to: "
                                           "bodies, springs and their rules, frictions, sensors, notes, and the "
                                           "drive's constants taken from the motor."),
          axis: Optional[str] = typer.Option(None, "--axis", help="With --lumped: only this axis (default: all)."),
          write_lumped: Optional[Path] = typer.Option(None, "--write-lumped", metavar="LUMPED.toml", dir_okay=False,
                                                      help="Write the model with each drive-chain axis replaced by "
                                                           "its plain type = \"lumped\" equivalent."),
          write: Optional[Path] = typer.Option(None, "--write", metavar="MODEL.toml", dir_okay=False,
                                               help="Save the validated model with the --set overrides applied "
                                                    "(catalogue parts record their values)."),
          json_: bool = JsonOption) -> None:
    """Validate a model file and summarise its axes, dofs and couplings."""
    with guarded(model):
        from ..io.atomic import check_outputs
        from ..robotics.lowering import axis_mechanics
        from .tables import check_payload, print_check

        check_outputs({"--write-lumped": (write_lumped, "model"), "--write": (write, "model")},
                      {"the model file": model})
        machine = load(model, set_)
        mechanics = {name: axis_mechanics(machine, name) for name in machine.axes}
        payload = check_payload(machine, mechanics)
        if lumped or axis is not None:
            from ..tasks.lumped import drive_chain_payload

            shown = [machine.axis_name(axis)] if axis is not None else list(machine.axes)
            for name in shown:
                payload["axes"][name]["drive_chain"] = drive_chain_payload(machine, name)
        if write_lumped is not None:
            from ..tasks.lumped import lumped_machine, write_lumped as save_lumped

            lumped_machine(machine)            # refused before anything is written
            save_lumped(machine, write_lumped, based_on=model)
            payload["written_lumped"] = str(write_lumped)
        if write is not None:
            from ..tasks.lumped import write_checked

            write_checked(machine, write, based_on=model, overrides=set_)
            payload["written"] = str(write)
        if json_:
            emit_json(payload)
        else:
            print_check(str(model), payload)
            if lumped or axis is not None:
                from .tables_chains import print_drive_chain

                for name, info in payload["axes"].items():
                    if "drive_chain" in info:
                        print_drive_chain(name, info["drive_chain"])
            for key, what in (("written_lumped", "lumped equivalent"), ("written", "model")):
                if key in payload:
                    typer.echo(f"wrote the {what} to {payload[key]}")


QOption = typer.Option(None, "--q", metavar="Q1,Q2,..",
                       help="A [robot] machine's configuration: every joint variable in frame order, elastic "
                            "joints included (m or rad, or with units: 150mm,30deg).")


@app.command()
def modal(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
          set_: Optional[List[str]] = SetOption, json_: bool = JsonOption,
          plot: Optional[Path] = PlotOption, q: Optional[str] = QOption) -> None:
    """Natural frequencies, damping ratios and mode shapes of an axis's mechanics."""
    with guarded(model):
        from ..io.atomic import check_outputs
        from ..errors import ModelError
        from ..mechanics.modal import modal_analysis
        from ..robotics.lowering import axis_mechanics

        check_outputs({"--plot": (plot, "figure")}, {"the model file": model})
        machine = load(model, set_)
        where: dict = {}
        if machine.robot is not None and axis is None:      # a robot: its structure, motors locked
            from ..tasks.robot import locked_modes

            name = None
            result, where = locked_modes(machine, q)
        else:
            if q is not None:
                if machine.robot is None:
                    raise ModelError("--q sets a [robot] machine's configuration; this model has no [robot] "
                                     "section", source="--q", value=q)
                from ..tasks.robot import joint_values

                machine = machine.model_copy(update={"robot": machine.robot.model_copy(
                    update={"configuration": joint_values(machine.robot, q, "q").tolist()})})
            name = machine.axis_name(axis)
            with progress_bar() as progress:
                result = modal_analysis(axis_mechanics(machine, name), progress=progress)
        if plot is not None:
            from ..plots.base import save_figure

            save_figure(result.plot(), plot)
        if json_:
            emit_json({"axis": name, **where, **result.to_dict()})
        else:
            from .tables import print_modal

            print_modal(name, result)


@app.command()
def modemap(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
            points: int = typer.Option(21, "--points", min=2, max=2001, metavar="N",
                                       help="Positions over the stroke, both ends included (with --joint: values "
                                            "per joint, at most 101 with two joints)."),
            modes: int = typer.Option(3, "--modes", min=1, max=1000, metavar="M",
                                      help="Flexible modes per position."),
            joint: Optional[List[str]] = typer.Option(
                None, "--joint", metavar="NAME=LOW:HIGH",
                help="A \\[robot] machine: sweep this joint over LOW..HIGH, with units (Y=0mm:400mm, "
                     "A2=-90deg:90deg); give one or two. The modes with every motor locked, or with --axis A "
                     "that axis's model (its motor free, the others locked)."),
            q: Optional[str] = typer.Option(None, "--q", metavar="Q1,Q2,..",
                                            help="With --joint: the configuration the other joints are held at "
                                                 "(every joint in frame order, as modal --q; default: the "
                                                 "model's)."),
            set_: Optional[List[str]] = SetOption, json_: bool = JsonOption,
            plot: Optional[Path] = PlotOption) -> None:
    """Mode map: a drive-chain axis's first flexible modes as the table travels over the stroke, or a \\[robot]
    machine's first modes as one or two joints sweep the workspace (--joint)."""
    with guarded(model):
        from ..io.atomic import check_outputs
        from ..tasks.modemap import mode_map

        check_outputs({"--plot": (plot, "figure")}, {"the model file": model})
        machine = load(model, set_)
        if joint or q is not None or machine.robot is not None:
            from ..tasks.workspace_map import workspace_mode_map

            with progress_bar() as progress:
                workspace = workspace_mode_map(machine, joint or [], points, modes, q=q, axis=axis,
                                               progress=progress)
            if plot is not None:
                from ..plots.base import save_figure

                save_figure(workspace.plot(), plot)
            if json_:
                emit_json(workspace.to_dict())
            else:
                from .tables_chains import print_workspace_map

                print_workspace_map(workspace.to_dict())
            return
        with progress_bar() as progress:
            result = mode_map(machine, axis, points, modes, progress=progress)
        if plot is not None:
            from ..plots.base import save_figure

            save_figure(result.plot(), plot)
        if json_:
            emit_json(result.to_dict())
        else:
            from .tables_chains import print_mode_map

            print_mode_map(result.to_dict())


CoupledOption = typer.Option(False, "--coupled",
                             help="A [robot] machine: analyse the axis with the other motorised joints' loops "
                                  "closed on the coupled model (the decoupled figures beside).")


@app.command()
def simulate(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
             duration: Optional[float] = typer.Option(None, "--duration", callback=number(gt=0, unit="s"),
                                                      help="Simulated time (s); "
                                                      "default: the move plus a settling margin."),
             step: Optional[float] = typer.Option(None, "--step", metavar="MM", callback=number(nonzero=True),
                                             help="Position step (mm)."),
             move: Optional[float] = typer.Option(None, "--move", metavar="MM", callback=number(nonzero=True),
                                                  help="Trapezoidal move (mm) with the model's or default limits."),
             max_velocity: Optional[float] = MaxVelocityOption,
             max_acceleration: Optional[float] = MaxAccelerationOption,
             gcode: Optional[Path] = typer.Option(None, "--gcode", metavar="FILE", dir_okay=False,
                                                  help="Follow a G-code path (G00-G03, G17, G90/G91) with the "
                                                       "axes it moves."),
             feed: Optional[float] = FeedOption,
             linear: bool = typer.Option(False, "--linear", help="Drop limits, quantizers and Coulomb friction."),
             magnification: Optional[float] = typer.Option(None, "--magnification", callback=magnification_option,
                                                           help="Scale of the contour error in the --gcode plot "
                                                                "(default: automatic, shown on the plot)."),
             out: Optional[Path] = typer.Option(None, "--out", help="Write every signal to this CSV file.",
                                                dir_okay=False),
             coupled: bool = typer.Option(False, "--coupled",
                                          help="A \\[robot] machine: move the axis while every other motorised "
                                               "joint holds its position, all loops on the coupled model; with "
                                               "--gcode, the path on the coupled nonlinear dynamics, read at the "
                                               "tool point."),
             set_: Optional[List[str]] = SetOption, json_: bool = JsonOption,
             plot: Optional[Path] = PlotOption) -> None:
    """Simulate the closed servo loop of an axis (hybrid, multi-rate, exact between samples)."""
    with guarded(model):
        from ..servo.loop import build_servo_loop
        from ..simulation import simulate as run_simulation
        from ..io.atomic import check_outputs
        from ..errors import ModelError
        from ..tasks.simulate import choose_profile, simulate_payload

        check_outputs({"--out": (out, "csv"), "--plot": (plot, "figure")},
                      {"the model file": model, "the G-code file (--gcode)": gcode})
        machine = load(model, set_)
        if gcode is not None and (step is not None or move is not None):
            raise ModelError("--gcode cannot be combined with --step or --move", source="options")
        if gcode is None and step is not None and move is not None:
            raise ModelError("give either --step or --move, not both", source="options")
        if coupled and gcode is None:
            from ..tasks.coupled import simulate_coupled_move

            if step is None and move is None and machine.axes[machine.axis_name(axis)].trajectory is None:
                raise ModelError("no setpoint: give --step MM or --move MM, or add a [axes.<name>.trajectory] table",
                                 source="options")
            with progress_bar() as progress:
                payload, run = simulate_coupled_move(machine, axis, step, move, max_velocity, max_acceleration,
                                                     duration, nonlinear=not linear, progress=progress)
            if run is None and (out is not None or plot is not None):
                payload["warnings"].append("nothing was written (--out, --plot): the run has no data")
            if run is not None and out is not None:
                run.to_csv(out)
            if run is not None and plot is not None:
                from ..plots.base import save_figure

                save_figure(run.plot(), plot)
            if json_:
                emit_json(payload)
            else:
                from .tables import print_coupled_axes, print_metrics

                print_metrics(payload["axis"], payload)
                print_coupled_axes(payload)
            exit_for(payload)
            return
        if gcode is not None:
            from ..tasks.simulate import simulate_gcode

            with progress_bar() as progress:
                payload, run = simulate_gcode(machine, gcode, feed, step, move, nonlinear=not linear,
                                              progress=progress, model="nonlinear" if coupled else "decoupled")
            if run is not None and out is not None:
                from ..io.csv import write_frame_csv

                write_frame_csv(run.to_pandas(), out)
            if run is not None and plot is not None:
                from ..plots.base import save_figure

                save_figure(run.plot(magnification), plot)
            if json_:
                emit_json(payload)
            else:
                from .tables import print_path, print_verdict

                if run is not None:
                    print_path(payload)
                print_verdict(payload, "axes")
            exit_for(payload)
            return
        from ..simulation.checks import diverged_verdict, simulation_verdict
        from ..simulation.kernel import SimulationDiverged
        from ..tasks.simulate import diverged_payload

        loop = build_servo_loop(machine, axis)
        if step is None and move is None and machine.axes[loop.axis].trajectory is None:
            raise ModelError("no setpoint: give --step MM or --move MM, or add a [axes.<name>.trajectory] table",
                             source="options")
        profile, default_duration = choose_profile(machine.axes[loop.axis].trajectory, step, move,
                                                   max_velocity, max_acceleration)
        try:
            with progress_bar() as progress:
                series = run_simulation(loop, profile, duration if duration is not None else default_duration,
                                        nonlinear=not linear, progress=progress)
        except SimulationDiverged as exc:
            from ..simulation import simulation_notes

            verdict = diverged_verdict(loop, exc)
            if out is not None or plot is not None:
                verdict = verdict.with_warnings(["nothing was written (--out, --plot): the run has no data"])
            payload = diverged_payload(loop, exc, verdict, simulation_notes(loop, not linear))
        else:
            if out is not None:
                series.to_csv(out)
            if plot is not None:
                from ..plots.base import save_figure

                save_figure(series.plot(), plot)
            payload = simulate_payload(series, simulation_verdict(loop, series, profile))
        if json_:
            emit_json(payload)
        else:
            from .tables import print_metrics

            print_metrics(loop.axis, payload)
        exit_for(payload)


@app.command()
def bode(model: Path = ModelArgument,
         loop: str = typer.Option("velocity-open", "--loop",
                                  help="One of: velocity-open, velocity-closed, position-open, position-closed, "
                                       "plant, compliance, following-error, disturbance."),
         axis: Optional[str] = AxisOption, points: int = typer.Option(2000, "--points", min=10, max=200000),
         nichols: bool = typer.Option(False, "--nichols", help="Draw a Nichols chart instead of a Bode plot."),
         coupled: bool = CoupledOption,
         set_: Optional[List[str]] = SetOption, json_: bool = JsonOption, plot: Optional[Path] = PlotOption) -> None:
    """Frequency response of a loop, with the digital effects exact (Bode or Nichols)."""
    with guarded(model):
        from ..servo.loop import build_servo_loop
        from ..frequency.loops import LoopAnalysis, default_omega
        from ..io.atomic import check_outputs
        from ..tasks.analysis import bode_payload

        check_outputs({"--plot": (plot, "figure")}, {"the model file": model})
        machine = load(model, set_)
        if coupled:
            _coupled_bode(machine, axis, loop, points, nichols, json_, plot)
            return
        servo = build_servo_loop(machine, axis)
        an = LoopAnalysis.of(servo)
        frf = an.response(loop, default_omega(servo, loop, points) if loop in _LOOP_NAMES else None)
        margins = None
        if frf.open_loop:
            from ..frequency.margins import stability_margins

            margins = stability_margins(frf)
        from ..tasks.analysis import response_verdict, verdict_subject

        verdict = response_verdict(servo, an, loop, margins)
        if plot is not None:
            from ..plots.frequency import bode_figure, nichols_figure
            from ..plots.base import save_figure

            figure = nichols_figure([frf], margins=margins) if nichols else bode_figure([frf], margins=margins)
            save_figure(figure, plot)
        payload = {**bode_payload(frf, margins), **verdict.to_dict()}
        if json_:
            emit_json(payload)
        else:
            from .tables import print_margins, print_verdict

            print_margins(servo.axis, {frf.name: margins} if margins is not None else {},
                          note=f"{frf.name}: {len(frf.omega)} points up to {frf.omega[-1]:.4g} rad/s")
            print_verdict(payload, verdict_subject(loop))
        exit_for(payload)


def _coupled_bode(machine, axis: Optional[str], loop: str, points: int, nichols: bool, json_: bool,
                  plot: Optional[Path]) -> None:
    """``bode --coupled``: the transfer with the other loops closed, beside the decoupled one."""
    from dataclasses import replace

    from ..tasks.coupled import coupled_bode

    payload, frf, margins, alone, alone_margins = coupled_bode(machine, axis, loop, points)
    if plot is not None:
        from ..plots.frequency import bode_figure, nichols_figure
        from ..plots.base import save_figure

        curves = [replace(frf, name=f"{frf.name} coupled"), replace(alone, name=f"{alone.name} decoupled")]
        marks = [margins, alone_margins] if margins is not None else None
        save_figure(nichols_figure(curves, margins=marks) if nichols else bode_figure(curves, margins=marks), plot)
    if json_:
        emit_json(payload)
    else:
        from rich.console import Console

        from ..tasks.analysis import verdict_subject
        from .tables import print_margins, print_verdict

        name = machine.axis_name(axis)
        print_margins(name, {f"{frf.name} coupled": margins, f"{alone.name} decoupled": alone_margins}
                      if margins is not None else {},
                      note=f"{frf.name} of axis {name} with the other loops closed: {len(frf.omega)} points up to "
                           f"{frf.omega[-1]:.4g} rad/s")
        for note in payload["notes"]:
            Console(highlight=False, soft_wrap=True).print(f"note: {note}")
        print_verdict(payload, f"coupled {verdict_subject(loop)}")
    exit_for(payload)


@app.command()
def margins(model: Path = ModelArgument, axis: Optional[str] = AxisOption, coupled: bool = CoupledOption,
            set_: Optional[List[str]] = SetOption, json_: bool = JsonOption) -> None:
    """Stability margins of the velocity and position loops (all crossovers; the worst reported)."""
    with guarded(model):
        from ..servo.loop import build_servo_loop
        from ..frequency.loops import LoopAnalysis
        from ..frequency.margins import stability_margins
        from ..tasks.analysis import margins_payload

        machine = load(model, set_)
        if coupled:
            from ..tasks.coupled import coupled_margins

            result = coupled_margins(machine, axis)
            if json_:
                emit_json(result.payload)
            else:
                from rich.console import Console

                from .tables import print_margins, print_verdict

                name = result.payload["axis"]
                print_margins(name, {f"{which} {label}": figures[which] for which in ("velocity", "position")
                                     for label, figures in (("coupled", result.coupled),
                                                            ("decoupled", result.decoupled))},
                              note=f"axis {name} with the other loops closed (coupled) and with the other motors "
                                   f"locked (decoupled)")
                for note in result.payload["notes"]:
                    Console(highlight=False, soft_wrap=True).print(f"note: {note}")
                print_verdict(result.payload, "coupled loops")
            exit_for(result.payload)
            return
        servo = build_servo_loop(machine, axis)
        an = LoopAnalysis.of(servo)
        velocity = stability_margins(an.response("velocity-open"))
        position = stability_margins(an.response("position-open"))
        payload = {"axis": servo.axis, **margins_payload(servo, an, velocity, position)}
        if json_:
            emit_json(payload)
        else:
            from .tables import print_margins, print_verdict

            print_margins(servo.axis, {"velocity": velocity, "position": position})
            print_verdict(payload, "loops")
        exit_for(payload)


@app.command()
def tune(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
         method: str = typer.Option("frequency", "--method", help="frequency (margins) or time (step responses)"),
         velocity_crossover: Optional[float] = typer.Option(None, "--velocity-crossover", metavar="RAD_S",
                                                            callback=number(gt=0, unit="rad/s"),
                                                            help="Default: 2*pi*f_meca/4."),
         velocity_phase_margin: float = typer.Option(45.0, "--velocity-phase-margin", metavar="DEG",
                                                    callback=number(gt=0, lt=180, unit="deg")),
         position_phase_margin: Optional[float] = typer.Option(None, "--position-phase-margin", metavar="DEG",
                                                               callback=number(gt=0, lt=180, unit="deg"),
                                                               help="Default 80 unless --position-crossover."),
         position_crossover: Optional[float] = typer.Option(None, "--position-crossover", metavar="RAD_S",
                                                            callback=number(gt=0, unit="rad/s")),
         min_gain_margin: float = typer.Option(6.0, "--min-gain-margin", metavar="DB",
                                                callback=number(gt=0, unit="dB")),
         apply_notch: bool = typer.Option(False, "--apply-notch",
                                          help="When a notch is suggested, write and report the tuning with it."),
         write: Optional[Path] = typer.Option(None, "--write", metavar="TUNED.toml", dir_okay=False,
                                              help="Write a copy of the model with the tuned controller."),
         all_positions: bool = typer.Option(False, "--all-positions",
                                            help="Components axis: tune where the first mode is lowest and "
                                                 "check the margins at every position of the mode map."),
         points: Optional[int] = typer.Option(None, "--points", min=2, max=2001, metavar="N",
                                              help="Positions checked by --all-positions (default 21)."),
         set_: Optional[List[str]] = SetOption, json_: bool = JsonOption) -> None:
    """Tune the cascade controller: frequency approach (margins, bandwidth) or time approach (steps)."""
    with guarded(model):
        from ..errors import ModelError
        from ..servo.loop import build_servo_loop
        from ..tasks.analysis import write_tuned

        if method not in ("frequency", "time"):
            raise ModelError("expected 'frequency' or 'time'", source="--method", value=method)
        if position_phase_margin is not None and position_crossover is not None:
            raise ModelError("give either --position-phase-margin or --position-crossover", source="options")
        if all_positions and method != "frequency":
            raise ModelError("--all-positions tunes with the frequency approach; leave out --method time",
                             source="--method", value=method)
        if points is not None and not all_positions:
            raise ModelError("--points sets the positions of --all-positions; add --all-positions", source="--points",
                             value=points)
        from ..io.atomic import check_outputs

        check_outputs({"--write": (write, "model")}, {"the model file": model})
        machine = load(model, set_)
        servo = build_servo_loop(machine, axis)
        if method == "time":
            from ..tuning.time import TimeTargets, tune_time

            with progress_bar() as progress:
                timed = tune_time(servo, TimeTargets(min_gain_margin=min_gain_margin), progress=progress)
            payload = timed.to_dict()
            gains = {"Kp": timed.Kp, "Kp_normalized": timed.Kp_normalized, "Ti": timed.Ti, "Kv": timed.Kv}
            notch = None
        else:
            from ..tuning.frequency import TuningTargets, tune_frequency

            targets = TuningTargets(velocity_crossover=velocity_crossover,
                                    velocity_phase_margin=velocity_phase_margin,
                                    position_phase_margin=None if position_crossover is not None
                                    else (position_phase_margin if position_phase_margin is not None else 80.0),
                                    position_crossover=position_crossover, min_gain_margin=min_gain_margin)
            over = None
            with progress_bar() as progress:
                if all_positions:
                    from ..tasks.tune_positions import tune_over_stroke

                    over = tune_over_stroke(machine, servo.axis, targets, points=points or 21,
                                            apply_notch=apply_notch, progress=progress)
                    result = over.result
                else:
                    result = tune_frequency(servo, targets, progress=progress)
            chosen = result.with_notch if apply_notch and result.with_notch is not None else result
            payload = {"method": "frequency", **chosen.to_dict()}
            if chosen is not result:
                payload["achieved"]["notch"] = result.notch
                payload["notch_applied"] = True
            elif result.with_notch is not None and result.with_notch.targets_met:
                payload["warnings"].append("the suggested notch would meet the targets: --apply-notch")
            payload["wall_time_s"] = result.wall_time_s
            if over is not None:
                over.update_payload(payload)
            t = chosen.tuned
            gains = {"Kp": t.Kp, "Kp_normalized": t.Kp_normalized, "Ti": t.Ti, "Kv": t.Kv}
            notch = result.notch if chosen is not result else None
        coupled_figures = None
        if machine.robot is not None:        # the tuned loop with the robot's other loops closed
            from ..tasks.coupled import coupled_tuning_check

            if method == "time":
                check = coupled_tuning_check(machine, servo.with_gains(Kp=timed.Kp, Ti=timed.Ti, Kv=timed.Kv),
                                             TimeTargets(min_gain_margin=min_gain_margin))
            else:
                check = coupled_tuning_check(machine, chosen.tuned_loop(), chosen.targets)
            payload["coupled_margins"], coupled_figures = check
            if not payload["coupled_margins"]["targets_met"]:
                payload["warnings"].append("with the other loops closed (coupled) the targets do not hold: "
                                           + "; ".join(payload["coupled_margins"]["unmet"]))
        if write is not None:
            write_tuned(machine, servo.axis, gains, notch, write, based_on=model, method=method)
            payload["written"] = str(write)
        if json_:
            emit_json({"axis": servo.axis, **payload})
        else:
            from .tables import print_margins, print_tuning, print_verdict

            print_tuning(servo.axis, payload)
            if "positions" in payload:
                from .tables_chains import print_stroke_tuning

                print_stroke_tuning(payload)
            if coupled_figures is not None:
                held = "hold" if payload["coupled_margins"]["targets_met"] else "do not hold"
                print_margins(servo.axis, {f"{which} coupled": m for which, m in coupled_figures.items()},
                              note=f"the tuned loop with the other loops closed (coupled): the targets {held}")
            print_verdict(payload, "tuned loop")
        exit_for(payload)


@app.command()
def circle(model: Path = ModelArgument,
           radius: float = typer.Option(..., "--radius", metavar="MM", callback=number(gt=0, unit="mm"),
                                       help="Circle radius (mm)."),
           feed: float = typer.Option(..., "--feed", metavar="MM_PER_MIN", callback=number(gt=0, unit="mm/min"),
                                     help="Feed rate (mm/min)."),
           ccw: bool = typer.Option(False, "--ccw", help="Counter-clockwise (G03); default clockwise (G02)."),
           feedforward: Optional[str] = typer.Option(None, "--feedforward", metavar="on|off",
                                                     help="Override the model's velocity and acceleration "
                                                          "feedforward on every axis."),
           magnification: Optional[float] = typer.Option(None, "--magnification", callback=number(gt=0),
                                                         help="Scale of the deviation in the polar plot."),
           circle_model: Optional[str] = typer.Option(None, "--model", metavar="MODEL",
                                                      help="decoupled, coupled or nonlinear: the model whose "
                                                           "figures are reported on a \\[robot] machine (default "
                                                           "nonlinear); the three are compared."),
           set_: Optional[List[str]] = SetOption, json_: bool = JsonOption, plot: Optional[Path] = PlotOption) -> None:
    """ISO 230-4 circle test (ballbar) on the X and Y axes: circular and radial deviation, reversal spikes,
    servo mismatch; on a \\[robot] machine also what the coupling of the axes adds (decoupled, coupled and
    nonlinear models compared)."""
    with guarded(model):
        from ..errors import ModelError
        from ..tasks.circle import circle_report

        if feedforward is not None and feedforward not in ("on", "off"):
            raise ModelError("expected 'on' or 'off'", source="--feedforward", value=feedforward)
        from ..io.atomic import check_outputs

        check_outputs({"--plot": (plot, "figure")}, {"the model file": model})
        machine = load(model, set_)
        with progress_bar() as progress:
            test, payload, tests = circle_report(machine, radius * 1e-3, feed * 1e-3 / 60.0, clockwise=not ccw,
                                                 feedforward=feedforward, model=circle_model, progress=progress)
        if plot is not None:
            if test.circle is not None:
                from ..plots.base import save_figure

                others = {name: other.circle for name, other in tests.items()
                          if other is not test and other.circle is not None}
                save_figure(test.plot(magnification, label=payload["model"], others=others), plot)
            else:
                payload["warnings"].append("no figure written (--plot): an axis is unstable")
        if json_:
            emit_json(payload)
        else:
            from .tables import print_circle, print_circle_coupling, print_verdict

            if test.circle is not None:
                print_circle(payload)
            if "coupling" in payload:
                print_circle_coupling(payload)
            print_verdict(payload, "axes")
        exit_for(payload)


@app.command()
def reduce(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
           method: str = typer.Option("modal", "--method",
                                      help="modal | balanced | balanced-dc | schur | hankel | physical"),
           order: Optional[int] = typer.Option(None, "--order", help="States of the reduced model "
                                               "(a rigid mode and one flexible mode make 4); default: the "
                                               "modes up to twice the velocity loop's Nyquist frequency."),
           keep: Optional[str] = typer.Option(None, "--keep", metavar="DOF,...",
                                              help="Bodies kept by the physical method."),
           band: Optional[str] = typer.Option(None, "--band", metavar="LOW_HZ:HIGH_HZ",
                                              help="Band of interest (errors, frequency-limited Gramians, "
                                                   "stiff-spring rule)."),
           inputs: Optional[str] = typer.Option(None, "--inputs", metavar="NAME[,NAME]",
                                                help="Actuators of the transfer to reduce; default: the drive's."),
           outputs: Optional[str] = typer.Option(None, "--outputs", metavar="NAME[,NAME]",
                                                 help="Sensors of the transfer to reduce; default: the "
                                                      "controller's position sensor."),
           write: Optional[Path] = typer.Option(None, "--write", metavar="REDUCED.toml", dir_okay=False,
                                                help="Write the reduced model (physical method)."),
           set_: Optional[List[str]] = SetOption, json_: bool = JsonOption, plot: Optional[Path] = PlotOption) -> None:
    """Reduce an axis's model: modal truncation, balanced (Gramian) truncation, physical regrouping."""
    with guarded(model):
        from ..errors import ModelError
        from ..tasks.reduce import METHODS, reduce_command

        if method not in METHODS:
            raise ModelError(f"expected one of {', '.join(METHODS)}", source="--method", value=method)
        if keep is not None and method != "physical":
            from ..tasks.reduce import parse_band, parse_keep

            parse_band(band)
            raise ModelError("--keep names bodies for --method physical; give --order N for this method",
                             source="--keep", value=",".join(parse_keep(keep) or []))
        if write is not None and method != "physical":
            raise ModelError("only the physical method gives a model file; the others give a state space",
                             source="--write", value=str(write))
        from ..io.atomic import check_outputs

        check_outputs({"--write": (write, "model"), "--plot": (plot, "figure")}, {"the model file": model})
        machine = load(model, set_)
        result = reduce_command(machine, axis, method, order, keep, band, inputs, outputs)
        if write is not None:
            from ..tasks.reduce import write_reduced

            write_reduced(result, write, based_on=model, axis=machine.axis_name(axis))
        if plot is not None:
            from ..plots.base import save_figure

            save_figure(result.plot(), plot)
        payload = result.to_dict()
        if write is not None:
            payload["written"] = str(write)
        if json_:
            emit_json(payload)
        else:
            from .tables import print_reduction

            print_reduction(payload)


@app.command()
def step(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
         loop: str = typer.Option("velocity", "--loop", help="velocity or position"),
         kp: Optional[float] = typer.Option(None, "--Kp-normalized", "--Kp", callback=number(gt=0, unit="1/s"),
                                            help="Velocity gain, normalised (1/s), as the model file's "
                                                 "Kp_normalized; default: the model's. (--Kp is the old name.)"),
         ti: Optional[float] = typer.Option(None, "--Ti", callback=number(gt=0, unit="s"),
                                           help="Integral time (s); default: the model's."),
         kv: Optional[float] = typer.Option(None, "--Kv", callback=number(gt=0, unit="1/s"),
                                           help="Position gain (1/s); default: the model's."),
         duration: Optional[float] = typer.Option(None, "--duration", callback=number(gt=0, unit="s"),
                                                   help="Length of the response (s)."),
         set_: Optional[List[str]] = SetOption, json_: bool = JsonOption, plot: Optional[Path] = PlotOption) -> None:
    """One step response of the sampled velocity or position loop, with its overshoot and rise time:
    the manual, step-by-step form of the time approach (paper III.B.3)."""
    with guarded(model):
        from ..errors import ModelError
        from ..servo.loop import build_servo_loop
        from ..frequency.loops import LoopAnalysis
        from ..tuning.time import position_step, velocity_step

        if loop not in ("velocity", "position"):
            raise ModelError("expected 'velocity' or 'position'", source="--loop", value=loop)
        from ..io.atomic import check_outputs

        check_outputs({"--plot": (plot, "figure")}, {"the model file": model})
        servo = build_servo_loop(load(model, set_), axis)
        an = LoopAnalysis.of(servo)
        Kp = servo.Kp if kp is None else kp * servo.m_rigid
        if ti is not None and servo.Ti == float("inf"):
            raise ModelError(f"a {servo.controller.type!r} velocity law has no integral time", source="--Ti", value=ti)
        Ti = servo.Ti if ti is None else ti
        Kv = servo.Kv if kv is None else kv
        response = velocity_step(an, Kp, Ti, duration) if loop == "velocity" else position_step(an, Kp, Ti, Kv, duration)
        from ..servo.stability import loop_verdict

        verdict = loop_verdict(servo, Kp=Kp, Ti=Ti, Kv=Kv, an=an,
                               loops=("velocity",) if loop == "velocity" else ("velocity", "position"))
        payload = {"axis": servo.axis, "loop": loop, "Kp": Kp, "Kp_normalized": Kp / servo.m_rigid, "Kp_si": Kp,
                   "Ti": Ti, "Kv": Kv, **response.to_dict(), **verdict.to_dict()}
        if plot is not None:
            from ..plots.base import save_figure

            save_figure(response.plot(f"{loop} loop step response"), plot)
        if json_:
            emit_json(payload)
        else:
            from rich.console import Console

            from .tables import print_verdict

            rise = "-" if response.rise_time is None else f"{response.rise_time * 1e3:.3g} ms"
            ti_text = "-" if Ti == float("inf") else f"{Ti:.4g} s"     # a P-TF law has no Ti
            over = "-" if payload["overshoot_percent"] is None else f"{payload['overshoot_percent']:.3g} %"
            Console(highlight=False, soft_wrap=True).print(
                f"{loop} loop, Kp_normalized = {payload['Kp_normalized']:.4g} 1/s, Ti = {ti_text}, "
                f"Kv = {Kv:.4g} 1/s: overshoot {over}, rise time {rise}")
            print_verdict(payload, f"{loop} loop")
        exit_for(payload)


@app.command()
def size(model: Path = ModelArgument, axis: Optional[str] = AxisOption,
         move: Optional[float] = typer.Option(None, "--move", metavar="MM", callback=number(nonzero=True),
                                              help="Size a trapezoidal move (mm) instead of the axis's trajectory."),
         max_velocity: Optional[float] = MaxVelocityOption,
         max_acceleration: Optional[float] = MaxAccelerationOption,
         gcode: Optional[Path] = typer.Option(None, "--gcode", metavar="FILE", dir_okay=False,
                                              help="Size the axis on a G-code path (the axes it moves are "
                                                   "simulated as by simulate --gcode)."),
         feed: Optional[float] = FeedOption,
         inertia_ratio_limit: float = typer.Option(10.0, "--inertia-ratio-limit", metavar="RATIO",
                                                   callback=number(gt=0),
                                                   help="Largest load/rotor inertia ratio accepted."),
         set_: Optional[List[str]] = SetOption, json_: bool = JsonOption) -> None:
    """Sizing check on the simulated controlled axis: peak and RMS motor torque (force), speed against the
    motor and the screw, back-EMF and voltage against the bus, inertia ratio, drive-train limits. Failing
    checks are listed first; they do not change the exit status (as tune's unmet targets), an unstable run does."""
    with guarded(model):
        from ..errors import ModelError
        from ..tasks.size import size_axis

        if gcode is not None and move is not None:
            raise ModelError("--gcode cannot be combined with --move", source="options")
        if move is None and (max_velocity is not None or max_acceleration is not None):
            raise ModelError("--max-velocity and --max-acceleration are the limits of --move; give --move MM",
                             source="options")
        if gcode is None and feed is not None:
            raise ModelError("--feed is the feed rate of a G-code path; give --gcode FILE", source="--feed", value=feed)
        machine = load(model, set_)
        with progress_bar() as progress:
            result = size_axis(machine, axis, move_mm=move, max_velocity=max_velocity,
                               max_acceleration=max_acceleration, gcode_path=gcode, feed_mm_min=feed,
                               inertia_ratio_limit=inertia_ratio_limit, progress=progress)
        payload = result.to_dict()
        if json_:
            emit_json(payload)
        else:
            from .tables import print_verdict
            from .tables_chains import print_sizing

            print_sizing(payload)
            print_verdict(payload, "loop")
        exit_for(payload)


@app.command()
def version(json_: bool = JsonOption) -> None:
    """The versions of sicomat, Python and the numerical libraries (for a bug report)."""
    from .versions import versions

    info = versions()
    if json_:
        emit_json(info)
    else:
        typer.echo(" ".join(f"{name} {value}" for name, value in info.items()))


_LOOP_NAMES = ("plant", "velocity-open", "velocity-closed", "position-open", "position-closed",
               "following-error", "compliance", "disturbance")


def main() -> None:
    """Run the ``sicomat`` program."""
    app()


if __name__ == "__main__":  # pragma: no cover
    main()
