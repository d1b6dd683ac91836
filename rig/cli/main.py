"""rig: control and acquisition for image-based BRDF goniophotometers (a simulated rig built in). Measure with
`rig run`, check with `rig plan` and `rig devices`, watch with `rig monitor`, and turn the dataset into fits,
predictions, exports, plots and a report; `rig COMMAND --help` for each."""

from __future__ import annotations

import argparse
import os
import sys
from collections import Counter
from dataclasses import replace
from pathlib import Path

from rig import __version__
from rig.acquisition.engine import NOMINAL_CAPTURE_S
from rig.acquisition.execute import RunOutcome
from rig.acquisition.preflight import prepare_run
from rig.acquisition.progress import ProgressBar, end_progress_lines, format_duration
from rig.acquisition.resume import prepare_resume
from rig.cli import bench, calibrate, export, fit, import_alta, monitor, plot, predict, report, sim
from rig.config.campaign import Campaign, CampaignError, check_campaign_for_rig, load_campaign
from rig.config.files import ConfigFileError
from rig.config.rigfile import RigConfig, load_rig_config, simulated_rig
from rig.core.errors import DeviceError
from rig.core.exits import EXIT_BROKEN_PIPE, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, fail
from rig.data.dataset_format import DatasetError
from rig.data.output_folder import default_output
from rig.devices import check_devices
from rig.drivers.interfaces import RigDevices
from rig.drivers.registry import installed_drivers
from rig.planning.candidates import candidate_plan
from rig.planning.plan import build_plan, estimate_rig_time_s, rig_time_comparison
from rig.planning.points import Plan, describe_reason
from rig.session.adaptive_sampler import planned_time_s, sampler_for
from rig.session.connect import open_campaign_rig, open_rig
from rig.session.warmup_estimate import expected_warmup


def plan_angle(deg: float) -> str:
    """A planned angle as the campaign gives it (84.99 stays 84.99, 30 reads 30.0): one decimal printed 84.99° as
    85.0°, an angle the rig would not be asked for."""
    return repr(round(deg, 6) + 0.0)


def print_adaptive_plan(plan: Plan, campaign: Campaign, rig: RigConfig) -> None:
    """An adaptive campaign's plan: the candidate domain, the first pass and when the batches stop."""
    spec, candidates = campaign.sampling, candidate_plan(campaign, rig)
    print(f"campaign {campaign.name}: adaptive sampling over {len(candidates.points)} candidate points at "
          f"{len(candidates.series)} incidences ({len(candidates.skipped)} more cannot be measured)")
    first = Counter((p.theta_i_deg, p.phi_i_deg) for p in plan.points)
    print(f"  first pass: {len(plan.points)} points, planned rig time {format_duration(planned_time_s(plan, rig))} "
          f"after warm-up ({len(spec.mandatory)} mandatory pairs)")
    warm = expected_warmup(campaign, rig)
    print(f"  before it, the lamp warm-up: {format_duration(rig.lamp.ramp_s + warm.seconds)} ({warm.source})")
    for (theta_i, phi_i), n in sorted(first.items()):
        print(f"    ({plan_angle(theta_i):>5s}°, {plan_angle(phi_i):>5s}°)  {n:4d}")
    stops = ([f"the planned rig time after warm-up reaches {format_duration(spec.budget_rig_time_s)}"]
             if spec.budget_rig_time_s is not None else []) + (
        [f"u/(f+τ) ≤ {spec.target_u_rel:g} at every candidate"] if spec.target_u_rel is not None else [])
    print(f"  then batches of up to {spec.batch_points} views at one incidence, where the interpolant is least "
          f"certain per second of rig time, until {' or '.join(stops)}")


def print_plan(plan: Plan, campaign: Campaign, rig: RigConfig) -> None:
    if campaign.sampling.mode == "adaptive":
        print_adaptive_plan(plan, campaign, rig)
        return
    print(f"campaign {campaign.name}: {len(plan.series)} incidence series, {plan.n_planned} planned points")
    print(f"  to measure: {len(plan.points)}")
    print(f"  skipped:    {len(plan.skipped)}")
    if (a := campaign.alignment) is not None:
        print(f"  first: align the arm on the specular peak at θi={a.theta_i_deg:g}° ({a.steps}×{a.steps} scan, "
              f"step {a.step_deg:g}°)")
    for reason, n in sorted(plan.skipped_by_reason().items(), key=lambda kv: -kv[1]):
        print(f"    {n:6d}  {reason}: {describe_reason(reason)}")
    print("  per series (θi, φi): measured / planned")
    measured = Counter(p.series for p in plan.points)
    planned = measured + Counter(p.series for p in plan.skipped)
    for s in plan.series:
        print(f"    {s.index:3d}  ({plan_angle(s.theta_i_deg):>5s}°, {plan_angle(s.phi_i_deg):>5s}°)  "
              f"{measured[s.index]:4d} / {planned[s.index]}")
    moves = estimate_rig_time_s(plan, rig.axes, NOMINAL_CAPTURE_S)
    warm = expected_warmup(campaign, rig)
    print(f"  estimated rig time: {format_duration(rig.lamp.ramp_s + warm.seconds + moves)} in {campaign.ordering} "
          "order, the lamp's warm-up included:")
    print(f"    lamp warm-up {format_duration(rig.lamp.ramp_s + warm.seconds)} (its {rig.lamp.ramp_s:g} s ramp, then "
          f"{format_duration(warm.seconds)}: {warm.source})")
    print(f"    points {format_duration(moves)} (moves + {NOMINAL_CAPTURE_S * 1e3:.0f} ms nominal capture per point; "
          "exposures depend on the sample)")
    if plan.points:
        table_s, optimised_s = rig_time_comparison(campaign, rig, NOMINAL_CAPTURE_S)
        print(f"  moves + capture: table order {format_duration(table_s)}, optimised order "
              f"{format_duration(optimised_s)} ({optimised_s / table_s:.2f} × table)")


def _rig_config(args: argparse.Namespace) -> RigConfig:
    """The --rig file, or the built-in simulated rig."""
    return load_rig_config(args.rig) if args.rig else simulated_rig()


def _load(args: argparse.Namespace) -> tuple[Campaign, RigConfig, Plan]:
    """Campaign, rig and plan of `rig run` and `rig plan`; ConfigFileError names the file."""
    campaign = load_campaign(args.campaign)
    rig = _rig_config(args)
    check_campaign_for_rig(campaign, rig, args.campaign)
    try:
        return campaign, rig, build_plan(campaign, rig)
    except CampaignError as exc:            # a mandatory pair of an adaptive campaign the rig cannot measure
        raise CampaignError(f"{args.campaign}: {exc}") from None


def cmd_plan(args: argparse.Namespace) -> int:
    try:
        campaign, rig, plan = _load(args)
    except ConfigFileError as exc:
        return fail(str(exc))
    print_plan(plan, campaign, rig)
    return EXIT_OK


def print_devices(devices: RigDevices) -> None:
    """Identity and state of every device; reads only, moves nothing."""
    for role, identity in devices.identities().items():
        print(f"{role:6s}  {identity}")
    for positioner in (devices.arm, devices.stage):
        positions = ", ".join(f"{ax.name} {ax.position_deg():.3f}°{' (moving)' if ax.is_moving() else ''}"
                              for ax in positioner.axes)
        print(f"        {positioner.name}: {positions}")
    lamp = devices.lamp
    print(f"        lamp: output {'ON' if lamp.output_is_on() else 'off'}, {lamp.measure_current_a():.3f} A, "
          f"{lamp.measure_voltage_v():.3f} V")
    s = devices.camera.sensor
    print(f"        camera: {s.width_px}×{s.height_px} px, {s.bit_depth} bit, exposures "
          f"{s.min_exposure_s:g}–{s.max_exposure_s:g} s")
    if devices.attenuator is not None:
        print(f"        attenuator: position {devices.attenuator.position()} of {devices.attenuator.positions}")


def cmd_devices(args: argparse.Namespace) -> int:
    if args.list:
        if args.check or args.rig_file:
            return fail("--list takes no rig file")
        print(f"{'driver':16s} {'role':12s} class  (package)")
        for driver in installed_drivers():
            print(driver.describe())
        return EXIT_OK
    if not args.rig_file:
        return fail("give a rig file, or --list")
    if args.check:
        return check_rig_file(args.rig_file)
    try:
        rig = load_rig_config(args.rig_file)
        check_devices(rig, args.rig_file)
        with open_rig(rig) as devices:
            print(f"rig {rig.name} ({'simulated' if rig.simulated else 'hardware'})")
            print_devices(devices)
    except ConfigFileError as exc:
        return fail(str(exc))
    except DeviceError as exc:
        print(f"rig: device error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def check_rig_file(path: str) -> int:
    """`rig devices --check`: the rig file, the drive maps and calibration file it names, and each device's
    driver (installed, its class imported, the entry's options taken), without opening any port or connection."""
    try:
        rig = load_rig_config(path)
        checked = check_devices(rig, path)
    except ConfigFileError as exc:
        return fail(str(exc))
    print(f"{path}: rig {rig.name} ({'simulated' if rig.simulated else 'hardware'}), valid")
    for line in checked or ["devices: the simulated rig's own, started in-process by each command"]:
        print(f"  {line}")
    if rig.camera.calibration_file:
        print(f"  camera calibration file {rig.camera.calibration_file}: read and usable")
    print("  nothing was opened or connected")
    return EXIT_OK


def cmd_resume(args: argparse.Namespace) -> int:
    """`rig run --resume DIR [--rig NEW.yaml]`: the campaign and the folder are the dataset's own, so a campaign
    file or `--out` given with it is refused rather than ignored."""
    if args.campaign or args.out:
        return fail(f"--resume {args.resume} continues the campaign the dataset was started with, in its own "
                    f"folder: give no {'campaign file' if args.campaign else '--out'} with it")
    try:
        r = prepare_resume(args.resume, force=args.force, rig_file=args.rig)
    except (ConfigFileError, DatasetError) as exc:
        return fail(str(exc))
    left = len(r.plan.points) - len(r.done_rows)
    print(f"rig {__version__}: resuming {r.campaign.name} in {args.resume}: {len(r.done_rows)} points done, "
          f"{left} to measure", file=sys.stderr)
    outcome = r.run(open_campaign_rig, progress=None if args.quiet else ProgressBar(), handle_signals=True,
                    sampler=sampler_for)
    return _report_outcome(outcome, len(r.plan.skipped))


def _report_outcome(outcome: RunOutcome, n_skipped: int) -> int:
    """How the run ended, on stderr (below the progress line), and its exit code."""
    end_progress_lines()
    if outcome.lamp_problem:
        print(f"rig: WARNING: THE LAMP MAY STILL BE ON: the lamp supply did not confirm it switched off "
              f"({outcome.lamp_problem}). Switch it off at the supply.", file=sys.stderr)
    if not outcome.written:             # the rig never came up, so the dataset folder was never made
        print(f"rig: campaign {'failed' if outcome.status == 'failed' else 'stopped'} before any point: "
              f"{outcome.error or 'interrupted while connecting'}; nothing was written ({outcome.out} was not "
              "created): run the same command again once the rig answers", file=sys.stderr)
        return EXIT_FAILED if outcome.status == "failed" else EXIT_INTERRUPTED
    if outcome.status == "failed":
        print(f"rig: campaign failed: {outcome.error}; {outcome.measured} completed points kept in {outcome.out}",
              file=sys.stderr)
        return EXIT_FAILED
    print(f"{outcome.status}: {outcome.measured} points measured, {n_skipped} skipped; "
          f"rig time {format_duration(outcome.rig_time_s)}, wall time {outcome.wall_s:.1f} s; "
          f"dataset in {outcome.out}" + ("" if outcome.status == "complete" else
                                        f" (continue with: rig run --resume {outcome.out})"),
          file=sys.stderr)
    return EXIT_OK if outcome.status == "complete" else EXIT_INTERRUPTED


def _sim_pace_problem() -> str | None:
    """A bad RIG_SIM_PACE (the simulated clock's pace) is bad input, refused before anything is written."""
    from rig.simulators.clock import pace_from_env  # only the simulated rig has a paced clock

    try:
        pace_from_env()
    except ValueError as exc:
        return str(exc)
    return None


def cmd_run(args: argparse.Namespace) -> int:
    if (problem := _sim_pace_problem()) is not None:
        return fail(problem)
    if args.resume:
        return cmd_resume(args)
    if not args.campaign:
        return fail("give a campaign file, or --resume DIR")
    try:
        campaign, rig = load_campaign(args.campaign), _rig_config(args)
        run = prepare_run(campaign, rig, Path(args.out) if args.out else default_output(Path(campaign.output.dir)),
                          campaign_file=args.campaign,
                          rig_file=args.rig or "<built-in rig>")
    except (ConfigFileError, DatasetError) as exc:
        return fail(str(exc))
    plan = run.plan
    where = "the simulated rig" if rig.simulated else f"rig {rig.name}"
    print(f"rig {__version__}: {campaign.name} on {where} → {run.out} "
          f"({len(plan.points)} points, {len(plan.skipped)} skipped)", file=sys.stderr)
    run = replace(run, warmup=expected_warmup(campaign, rig))        # the first ETA's warm-up, as `rig plan`'s
    try:
        outcome = run.run(open_campaign_rig, progress=None if args.quiet else ProgressBar(), handle_signals=True,
                          sampler=sampler_for)
    except DatasetError as exc:         # the folder could not be made once the rig was up: nothing written
        return fail(str(exc))
    return _report_outcome(outcome, len(plan.skipped))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rig", description=__doc__)
    parser.add_argument("--version", action="version", version=f"rig {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="measure a campaign (by default on the built-in simulated rig)")
    p_run.add_argument("campaign", nargs="?", help="campaign YAML file")
    p_run.add_argument("--out", help="dataset folder, new or empty (default: the campaign's output.dir, or "
                                      "output.dir-YYYYMMDD-HHMMSS when that is taken)")
    p_run.add_argument("--resume", metavar="DIR", help="continue an interrupted or failed campaign in DIR")
    p_run.add_argument("--force", action="store_true", help="with --resume: even if the campaign file changed")
    p_run.add_argument("--rig", help="rig file (default: the built-in simulated rig); with --resume: the same "
                                      "instruments reached at new addresses (default: the rig the dataset recorded)")
    p_run.add_argument("--quiet", action="store_true", help="no progress bar")
    p_run.set_defaults(func=cmd_run)
    p_plan = sub.add_parser("plan", help="print the plan: points, skipped points by reason, rig time")
    p_plan.add_argument("campaign", help="campaign YAML file")
    p_plan.add_argument("--rig", help="rig file (default: the built-in simulated rig)")
    p_plan.set_defaults(func=cmd_plan)
    p_dev = sub.add_parser("devices", help="connect, print each device's identity and state; moves nothing "
                                           "(--check: check the rig file without connecting)")
    p_dev.add_argument("rig_file", metavar="RIG.yaml", nargs="?", help="rig file, e.g. campaigns/rigs/simulated.yaml")
    p_dev.add_argument("--check", action="store_true",
                       help="check the rig file, its drive maps and calibration file, and every device's driver "
                            "(installed, importable, takes the entry's options) without opening any port")
    p_dev.add_argument("--list", action="store_true",
                       help="list every installed driver (entry-point group rig.drivers): name, role, class, package")
    p_dev.set_defaults(func=cmd_devices)
    for module in (fit, import_alta, export, predict, plot, report, monitor, bench, sim, calibrate):
        module.add_subcommand(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        code = args.func(args)
        sys.stdout.flush()           # a closed pipe shows here, not in the interpreter's exit
    except BrokenPipeError:
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    return code


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail a second time."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return                       # not a real file (captured): nothing will be flushed to a pipe
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
