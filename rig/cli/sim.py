"""`rig sim serve`: the simulated rig as a standalone instrument server (rig.simulators.served)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from types import FrameType

from rig.config.campaign import load_campaign
from rig.config.files import ConfigFileError
from rig.config.rigfile import load_rig_config, simulated_rig
from rig.core.exits import EXIT_OK, fail

#: How often (wall seconds) the server lets the lamp supply's watchdog act without a command.
TICK_S = 0.005


def cmd_serve(args: argparse.Namespace) -> int:
    """Start the peers, write the client rig file, serve until SIGINT/SIGTERM, then remove the file."""
    from rig.simulators.served import PAPER_RM1, ServedRig, write_rig_file  # only this command needs them

    out = Path(args.rig_file)
    try:
        base = load_rig_config(args.base) if args.base else simulated_rig()
        sample = PAPER_RM1
        if args.campaign:
            truth = load_campaign(args.campaign).sample.simulated_brdf
            if truth is None:
                return fail(f"{args.campaign}: key 'sample.simulated_brdf' is needed to serve its sample")
            sample = (truth.model, truth.params)
    except ConfigFileError as exc:
        return fail(str(exc))
    if not 0 < args.speed <= 1000:
        return fail(f"--speed {args.speed:g}: must be above 0 and at most 1000")
    if not out.parent.is_dir():
        return fail(f"--rig-file {out}: folder {out.parent} does not exist")
    stop = threading.Event()

    def request_stop(signum: int, frame: FrameType | None) -> None:
        stop.set()
    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    served = ServedRig(base, *sample, speed=args.speed)
    try:
        client = served.start()
        write_rig_file(client, out)
        print(f"rig sim serve: {base.name} rig (sample {sample[0]}) at {args.speed:g}× wall time; rig file {out}; "
              "SIGINT or SIGTERM stops it", flush=True)
        while not stop.wait(TICK_S):
            message = served.tick()
            if message:
                print(f"rig sim serve: {message}", file=sys.stderr, flush=True)
    finally:
        out.unlink(missing_ok=True)
        served.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print("rig sim serve: stopped", flush=True)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig sim serve --rig-file PATH [--rig BASE] [--campaign FILE] [--speed N]`."""
    sim = subparsers.add_parser("sim", help="the simulated rig outside `rig run`")
    which = sim.add_subparsers(dest="sim", required=True)
    serve = which.add_parser("serve", help="serve the simulated rig's instruments on loopback for other processes")
    serve.add_argument("--rig-file", required=True, metavar="PATH",
                       help="where to write the rig file clients use (`rig run --rig PATH`); removed on exit")
    serve.add_argument("--rig", dest="base", metavar="RIG.yaml",
                       help="rig to simulate: geometry, axes, camera, lamp, simulation (default: the built-in one)")
    serve.add_argument("--campaign", metavar="FILE",
                       help="serve this campaign's sample.simulated_brdf (default: the paper's RM1)")
    serve.add_argument("--speed", type=float, default=1.0,
                       help="rig seconds per wall second (default 1); the rig file carries it to clients")
    serve.set_defaults(func=cmd_serve)
