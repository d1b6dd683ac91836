"""`rig sim serve`: the simulated rig as a standalone instrument server (rig.simulators.served)."""

from __future__ import annotations

import argparse
import os
import signal
import stat
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
    """Start the peers, write the client rig file, serve until SIGINT/SIGTERM, then remove the file it wrote.

    Nothing already at `--rig-file` is ever overwritten or removed: it is refused (exit 2) before serving."""
    from rig.simulators.served import PAPER_RM1, ServedRig, remove_rig_file, write_rig_file  # only this command

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
    if os.path.lexists(out):
        return fail(_exists_message(out))
    stop = threading.Event()

    def request_stop(signum: int, frame: FrameType | None) -> None:
        stop.set()
    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    served = ServedRig(base, *sample, speed=args.speed)
    written: tuple[int, int] | None = None
    try:
        client = served.start()
        try:
            written = write_rig_file(client, out)
        except FileExistsError:             # something appeared at the path since the check above
            return fail(_exists_message(out))
        except OSError as exc:              # a read-only folder, a file system without hard links
            return fail(f"--rig-file {out}: cannot write it there: {exc.strerror or exc}")
        print(f"rig sim serve: {base.name} rig (sample {sample[0]}) at {args.speed:g}× wall time; rig file {out}; "
              "SIGINT or SIGTERM stops it", flush=True)
        while not stop.wait(TICK_S):
            message = served.tick()
            if message:
                print(f"rig sim serve: {message}", file=sys.stderr, flush=True)
    finally:
        if written is not None:
            remove_rig_file(out, written)
        served.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print("rig sim serve: stopped", flush=True)
    return EXIT_OK


def _exists_message(path: Path) -> str:
    """The refusal of a `--rig-file` path where something already is, saying what it is."""
    mode = os.lstat(path).st_mode if os.path.lexists(path) else 0
    kinds = ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
             (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))
    what = next((name for test, name in kinds if test(mode)), "a file")
    return (f"--rig-file {path}: {what} is already there; rig sim serve writes a new file and never "
            "overwrites or removes anything it did not create: choose another path")


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig sim serve --rig-file PATH [--rig BASE] [--campaign FILE] [--speed N]`."""
    sim = subparsers.add_parser("sim", help="the simulated rig outside `rig run`")
    which = sim.add_subparsers(dest="sim", required=True)
    serve = which.add_parser("serve", help="serve the simulated rig's instruments on loopback for other processes")
    serve.add_argument("--rig-file", required=True, metavar="PATH",
                       help="where to write the rig file clients use (`rig run --rig PATH`): a new file, refused if "
                            "anything is there; removed on exit")
    serve.add_argument("--rig", dest="base", metavar="RIG.yaml",
                       help="rig to simulate: geometry, axes, camera, lamp, simulation (default: the built-in one)")
    serve.add_argument("--campaign", metavar="FILE",
                       help="serve this campaign's sample.simulated_brdf (default: the paper's RM1)")
    serve.add_argument("--speed", type=float, default=1.0,
                       help="rig seconds per wall second (default 1); the rig file carries it to clients")
    serve.set_defaults(func=cmd_serve)
