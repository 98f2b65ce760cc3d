"""``python -m ekfslam simulate --trajectory T --out DIR``: the seed's robot, as a run folder."""

from __future__ import annotations

import argparse
import math

from ekfslam.cli import args as ca
from ekfslam.core.arena import SEED_ARENA
from ekfslam.logs.runlog import SIMULATED_DECIMALS, write_run
from ekfslam.sim.config import REALISTIC_ERRORS
from ekfslam.sim.scenarios import ROBOTS
from ekfslam.sim.simulation import SimulationConfig, simulate

#: The simulated path must stay this far inside the seed's arena walls (m).
ARENA_MARGIN = 0.05
#: Laps: 100 laps of the largest square take about 4500 s, within the controller's 10^4 s.
MAX_LAPS = 100


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``simulate`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    sim = subparsers.add_parser(name, help=help)
    sim.add_argument("--trajectory", choices=["square", "octagon"], required=True)
    sim.add_argument(
        "--laps",
        type=ca.whole(1, MAX_LAPS, why="the controller's time limit"),
        default=2,
        help=f"laps, 1 to {MAX_LAPS} (default: %(default)s)",
    )
    sim.add_argument(
        "--size",
        type=ca.positive(),
        help="side of the square / size of the octagon, m; the path must stay "
        f"{ARENA_MARGIN * 100:.0f} cm inside the seed's arena",
    )
    sim.add_argument("--seed", type=ca.seed(), default=1)
    sim.add_argument(
        "--start-error",
        type=ca.finite(),
        nargs=3,
        metavar=("DX", "DY", "DTHETA"),
        help="the robot's true placement error, m, m, rad, within ±0.5 m and ±π "
        "(default: drawn from the seed)",
    )
    sim.add_argument(
        "--wheel-scale-sigma",
        type=ca.non_negative(0.3, why="a 3σ scale must stay positive"),
        help="std of a per-wheel calibration error (a fraction; default 0: none)",
    )
    sim.add_argument(
        "--scenario",
        choices=ROBOTS,
        default="ideal",
        help="the robot: ideal (default), or realistic: the systematic errors of a real "
        "classroom robot (tag placement, range scale, wheel radius and wheelbase, slip, motor "
        "lag, camera latency; see ekfslam.sim.config.REALISTIC)",
    )
    ca.add_run_folder_arguments(sim)
    sim.add_check(_check_path_in_arena)
    sim.add_check(ca.triple_check("--start-error", (0.5, 0.5, math.pi), ("DX", "DY", "DTHETA")))
    sim.add_check(_check_start_in_arena)
    sim.set_defaults(func=cmd_simulate)


def _check_path_in_arena(args: argparse.Namespace) -> str | None:
    """The simulated path must stay inside the seed's arena, whose walls hold every tag."""
    if args.size is None:
        return None
    # the square's corners lie at ±size/2; the octagon's vertices at size/√2 on the axes
    reach = args.size / 2.0 if args.trajectory == "square" else args.size / math.sqrt(2.0)
    limit = SEED_ARENA.half_size - ARENA_MARGIN
    if reach > limit:
        largest = 2.0 * limit if args.trajectory == "square" else math.sqrt(2.0) * limit
        return (
            f"argument --size: the {args.trajectory} must stay {ARENA_MARGIN * 100:.0f} cm "
            f"inside the arena's walls (±{SEED_ARENA.half_size:g} m): at most {largest:.3f} m, "
            f"got {args.size:g}"
        )
    return None


def _check_start_in_arena(args: argparse.Namespace) -> str | None:
    """The robot's true start (the nominal start plus ``--start-error``) must be inside the arena:
    a start through a wall gives a run no real robot could have made."""
    if args.start_error is None:
        return None
    x, y = (n + e for n, e in zip(SEED_ARENA.nominal_start[:2], args.start_error[:2], strict=True))
    if SEED_ARENA.contains((x, y)):
        return None
    return (
        f"argument --start-error: the robot would start at ({x:g}, {y:g}) m, outside the arena "
        f"(walls at ±{SEED_ARENA.half_size:g} m; the nominal start is "
        f"({SEED_ARENA.nominal_start[0]:g}, {SEED_ARENA.nominal_start[1]:g}))"
    )


def cmd_simulate(args: argparse.Namespace) -> int:
    kwargs = {"trajectory": args.trajectory, "laps": args.laps, "seed": args.seed}
    if args.size is not None:
        kwargs["size"] = args.size
    if args.start_error is not None:
        kwargs["start_error"] = tuple(args.start_error)
    if args.wheel_scale_sigma is not None:
        kwargs["wheel_scale_sigma"] = args.wheel_scale_sigma
    if args.scenario == "realistic":
        kwargs |= REALISTIC_ERRORS
    run = simulate(SimulationConfig(**kwargs))
    write_run(
        run,
        args.out,
        overwrite=args.overwrite,
        overwrite_hint="--overwrite",
        decimals=SIMULATED_DECIMALS,
    )
    print(
        f"wrote {args.out} ({run.meta.name}): {len(run.controls.t)} controls, "
        f"{len(run.detections.t)} detections, "
        f"{run.controls.t[-1] - run.controls.t[0]:.1f} s of simulated time"
    )
    return 0
