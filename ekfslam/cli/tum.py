"""``python -m ekfslam tum RUN [--robot N] --out DIR``: replay a run and export it for `evo`."""

from __future__ import annotations

import argparse

from ekfslam.cli import args as ca
from ekfslam.cli.common import add_iterations_argument, load_run, noise_from_args
from ekfslam.logs import tum
from ekfslam.logs.tum import export_tum
from ekfslam.pipeline import replay


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``tum`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=tum.__doc__.split("\n\n")[0])
    p.add_argument("run", type=ca.given_path, help="a run folder or a MRCLAM dataset folder")
    ca.add_robot_argument(p)
    ca.add_replay_start_arguments(p)
    p.add_argument(
        "--out",
        type=ca.output_folder,
        required=True,
        help="folder for the .tum files (created if missing)",
    )
    ca.add_noise_arguments(p)
    add_iterations_argument(p)
    p.set_defaults(func=cmd_tum)


def cmd_tum(args: argparse.Namespace) -> int:
    run, _report = load_run(args)
    noise, config = noise_from_args(args, run)
    written = export_tum(run, replay(run, noise, config), args.out)
    for name in sorted(written):
        print(written[name])
    return 0
