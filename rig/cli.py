"""Command line: `rig run CAMPAIGN.yaml`, `rig plan CAMPAIGN.yaml`."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rig import __version__
from rig.campaign import Campaign, CampaignError, campaign_sha256, load_campaign
from rig.dataset import DatasetError, DatasetWriter
from rig.plan import SKIP_REASONS, Plan, build_plan, estimate_rig_time_s
from rig.progress import ProgressBar, format_duration
from rig.rigconfig import RigConfig
from rig.runner import Runner

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130

#: Nominal capture time per point for plan estimates: probe, one main exposure, readouts.
NOMINAL_CAPTURE_S = 0.05


def _fail(message: str) -> int:
    print(f"rig: error: {message}", file=sys.stderr)
    return EXIT_BAD_INPUT


def manifest_for(campaign: Campaign, campaign_path: Path, rig: RigConfig) -> dict:
    manifest = {
        "campaign": {"name": campaign.name, "file": str(campaign_path),
                     "sha256": campaign_sha256(campaign_path), "content": campaign.model_dump(mode="json")},
        "sample": campaign.sample.model_dump(mode="json", exclude={"simulated_brdf"}),
        "rig": {"name": rig.name, "simulated": rig.simulated, "config": rig.model_dump(mode="json")},
        "software": {"name": "rig", "version": __version__},
        "counts": {},
    }
    if rig.simulated and campaign.sample.simulated_brdf is not None:
        manifest["simulated_brdf"] = campaign.sample.simulated_brdf.model_dump(mode="json")
    return manifest


def print_plan(plan: Plan, campaign: Campaign, rig: RigConfig) -> None:
    print(f"campaign {campaign.name}: {len(plan.series)} incidence series, {plan.n_planned} planned points")
    print(f"  to measure: {len(plan.points)}")
    print(f"  skipped:    {len(plan.skipped)}")
    for reason, n in sorted(plan.skipped_by_reason().items(), key=lambda kv: -kv[1]):
        print(f"    {n:6d}  {reason}: {SKIP_REASONS[reason]}")
    print("  per series (θi, φi): measured / planned")
    for s in plan.series:
        n_meas = sum(p.series == s.index for p in plan.points)
        n_all = n_meas + sum(p.series == s.index for p in plan.skipped)
        print(f"    {s.index:3d}  ({s.theta_i_deg:5.1f}°, {s.phi_i_deg:5.1f}°)  {n_meas:4d} / {n_all}")
    moves = estimate_rig_time_s(plan, rig, NOMINAL_CAPTURE_S)
    warm = campaign.lamp.warmup_min_s + campaign.lamp.warmup_check_s
    print(f"  estimated rig time: {format_duration(moves + warm)} "
          f"(moves + {NOMINAL_CAPTURE_S * 1e3:.0f} ms nominal capture per point + ≥ {warm:.0f} s lamp warm-up; "
          "exposures depend on the sample)")


def _load(args) -> tuple[Campaign, RigConfig, Plan]:
    campaign = load_campaign(args.campaign)
    rig = RigConfig()
    return campaign, rig, build_plan(campaign, rig)


def cmd_plan(args) -> int:
    try:
        campaign, rig, plan = _load(args)
    except CampaignError as exc:
        return _fail(str(exc))
    print_plan(plan, campaign, rig)
    return EXIT_OK


def cmd_run(args) -> int:
    from simulators.rig import build_simulated_rig   # the simulated rig is the default rig

    try:
        campaign, rig, plan = _load(args)
    except CampaignError as exc:
        return _fail(str(exc))
    if campaign.sample.simulated_brdf is None:
        return _fail(f"{args.campaign}: key 'sample.simulated_brdf' is required on the simulated rig "
                     "(the sample's true BRDF: model and params)")
    if not plan.points:
        return _fail(f"{args.campaign}: no point of the campaign can be measured "
                     f"(skipped: {plan.skipped_by_reason()})")
    out = Path(args.out or campaign.output.dir)
    try:
        writer = DatasetWriter(out, manifest_for(campaign, Path(args.campaign), rig))
    except DatasetError as exc:
        return _fail(str(exc))
    writer.write_skipped(plan.skipped)
    truth = campaign.sample.simulated_brdf
    devices, _world = build_simulated_rig(rig, truth.model, truth.params)
    print(f"rig {__version__}: {campaign.name} on the simulated rig → {out} "
          f"({len(plan.points)} points, {len(plan.skipped)} skipped)", file=sys.stderr)
    wall0 = time.perf_counter()
    runner = Runner(campaign, plan, devices, writer, rig,
                    progress=None if args.quiet else ProgressBar())
    try:
        status = runner.run()
    except Exception as exc:
        print(f"rig: campaign failed: {exc}; {runner.measured} completed points kept in {out}",
              file=sys.stderr)
        return EXIT_FAILED
    finally:
        writer.close()
        devices.close()
    wall = time.perf_counter() - wall0
    print(f"{status}: {runner.measured} points measured, {len(plan.skipped)} skipped; "
          f"rig time {format_duration(runner.rig_time())}, wall time {wall:.1f} s; dataset in {out}",
          file=sys.stderr)
    return EXIT_OK if status == "complete" else EXIT_INTERRUPTED


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rig", description=__doc__)
    parser.add_argument("--version", action="version", version=f"rig {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="measure a campaign (on the built-in simulated rig)")
    p_run.add_argument("campaign", help="campaign YAML file")
    p_run.add_argument("--out", help="dataset folder (default: output.dir of the campaign)")
    p_run.add_argument("--quiet", action="store_true", help="no progress bar")
    p_run.set_defaults(func=cmd_run)
    p_plan = sub.add_parser("plan", help="print the plan: points, skipped points by reason, rig time")
    p_plan.add_argument("campaign", help="campaign YAML file")
    p_plan.set_defaults(func=cmd_plan)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
