"""The command line: ``python -m ekfslam run|simulate|fetch ...``.

Bad input ends with one line on stderr that names the file, the line and the problem, and exit
status 2; never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

from ekfslam.errors import EkfSlamError, InputError
from ekfslam.evaluation import SEED_TABLE1

EXIT_BAD_INPUT = 2

#: Modules with an ``add_cli(subparsers)`` that registers a subcommand (``set_defaults(func=...)``).
_COMMAND_MODULES: tuple[str, ...] = (
    "ekfslam.fetch",
    "ekfslam.mrclam",
    "ekfslam.rosbag",
    "ekfslam.tum",
    "ekfslam.frames",
    "ekfslam.visioneval",
    "ekfslam.consistency",
    "ekfslam.bench",
)


def add_noise_arguments(p: argparse.ArgumentParser) -> None:
    from ekfslam.filter import CHI2_2DOF_99

    g = p.add_argument_group("noise (R, eq. 9, and Q, eq. 11) and filter options")
    g.add_argument("--sigma-x", type=float, help="motion noise along the body x axis, m/√s")
    g.add_argument("--sigma-y", type=float, help="motion noise along the body y axis, m/√s")
    g.add_argument("--sigma-theta", type=float, help="heading noise, rad/√s")
    g.add_argument("--sigma-range", type=float, help="range noise σ_r, m")
    g.add_argument("--sigma-bearing", type=float, help="bearing noise σ_φ, rad")
    g.add_argument(
        "--init", choices=["inverse", "seed"], default="inverse",
        help="landmark initialisation: inverse observation (default) or the seed's eq. (3)",
    )  # fmt: skip
    g.add_argument(
        "--gate", type=float, default=CHI2_2DOF_99,
        help="NIS gate (chi-square, 2 dof); 0 turns gating off (default: %(default).2f)",
    )  # fmt: skip
    g.add_argument(
        "--reinit-after", type=int,
        help="re-initialise a landmark after this many agreeing rejected sightings; 0: never "
        "(default: 3, but never for MRCLAM)",
    )  # fmt: skip


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m ekfslam",
        description="Landmark EKF SLAM after the UCSD CSE276A HW3 report.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="replay a run (our run-log folder, or a MRCLAM dataset)")
    run.add_argument(
        "run", type=Path, help="a run folder (run.json ...) or a MRCLAM dataset folder"
    )
    run.add_argument("--robot", type=int, help="MRCLAM only: which robot (1-5)")
    run.add_argument("--plot", type=Path, help="write the seed's Figure 2 for the run to FILE")
    run.add_argument("--json", action="store_true", help="print one JSON object")
    run.add_argument(
        "--align", choices=["mean_distance", "least_squares"], default="mean_distance",
        help="eq. (17) objective: mean distance (the seed's) or least squares",
    )  # fmt: skip
    add_noise_arguments(run)
    run.set_defaults(func=cmd_run)

    sim = sub.add_parser("simulate", help="simulate the seed's robot and write a run folder")
    sim.add_argument("--trajectory", choices=["square", "octagon"], required=True)
    sim.add_argument("--laps", type=int, default=2)
    sim.add_argument("--size", type=float, help="side of the square / size of the octagon, m")
    sim.add_argument("--seed", type=int, default=1)
    sim.add_argument(
        "--start-error", type=float, nargs=3, metavar=("DX", "DY", "DTHETA"),
        help="the robot's true placement error, m, m, rad (default: drawn from the seed)",
    )  # fmt: skip
    sim.add_argument(
        "--wheel-scale-sigma", type=float,
        help="std of a per-wheel calibration error (a fraction; default 0: none)",
    )  # fmt: skip
    sim.add_argument("--out", type=Path, required=True, help="the run folder to write")
    sim.add_argument("--overwrite", action="store_true", help="replace an existing run folder")
    sim.set_defaults(func=cmd_simulate)

    # Commands that live with their concept: each module adds its own subparser.
    for module in _COMMAND_MODULES:
        importlib.import_module(module).add_cli(sub)
    return parser


def load_run(args: argparse.Namespace):
    """A RunLog from either format, plus a note on anything the loader dropped."""
    folder: Path = args.run
    if (folder / "Barcodes.dat").is_file():
        from ekfslam.mrclam import load_mrclam

        if args.robot is None:
            raise InputError(folder, None, "a MRCLAM dataset needs --robot N (1-5)")
        run, report = load_mrclam(folder, args.robot)
        return run, report
    if args.robot is not None:
        raise InputError(folder, None, "--robot is only for MRCLAM datasets (no Barcodes.dat)")
    # A run logged as camera frames, with no detections.csv yet: detect the tags in its frames.
    from ekfslam.frames import has_frames_only, read_frames_run

    if has_frames_only(folder):
        return read_frames_run(folder)
    from ekfslam.runlog import read_run

    return read_run(folder), None


def noise_from_args(args: argparse.Namespace, run):
    from dataclasses import replace

    from ekfslam.replay import NoiseConfig, default_config, default_noise

    base = default_noise(run)
    overrides = {
        name: getattr(args, name)
        for name in ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")
        if getattr(args, name) is not None
    }
    noise = NoiseConfig(**{**base.__dict__, **overrides})
    config = replace(
        default_config(run), init=args.init, gate=None if args.gate == 0 else args.gate
    )
    if args.reinit_after is not None:
        config = replace(config, reinit_after=args.reinit_after or None)
    return noise, config


def cmd_run(args: argparse.Namespace) -> int:
    from ekfslam.evaluation import summarize
    from ekfslam.replay import replay

    run, report = load_run(args)
    noise, config = noise_from_args(args, run)
    result = replay(run, noise, config)
    summary = summarize(run, result, method=args.align)
    out = summary.as_dict()
    if report is not None:
        out["dropped"] = report.as_dict()
    if args.plot is not None:
        from ekfslam.plotting import figure2

        fig = figure2(run, result, arena_half_size=_arena_half_size(run))
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=120)
        out["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(_table(summary, out))
    return 0


def _arena_half_size(run) -> float | None:
    """The seed's arena walls are drawn when the run's tag map is the seed's."""
    from ekfslam.arena import SEED_ARENA

    tags = run.meta.tag_map or {}
    seed = SEED_ARENA.tag_map()
    same = tags.keys() == seed.keys() and all(
        abs(tags[i][0] - seed[i][0]) < 1e-9 and abs(tags[i][1] - seed[i][1]) < 1e-9 for i in seed
    )
    return SEED_ARENA.half_size if same else None


def _table(summary, out: dict) -> str:
    lines = []
    a = summary.alignment
    header = f"{'Trajectory':<22}{'x0':>9}{'y0':>9}{'theta0':>9}{'Average Error':>15}"
    lines.append(header)
    if a is None:
        lines.append(f"{summary.name:<22}  (no alignment: {summary.alignment_note})")
    else:
        lines.append(
            f"{summary.name:<22}{a.x0:>9.3f}{a.y0:>9.3f}{a.theta0:>9.3f}{a.mean_error:>15.3f}"
        )
        for key, (x0, y0, t0, err) in SEED_TABLE1.items():
            if summary.name.startswith(key):
                lines.append(
                    f"{'  seed report (real)':<22}{x0:>9.3f}{y0:>9.3f}{t0:>9.3f}{err:>15.3f}"
                )
        sp = summary.start_pose
        lines.append(f"recovered start pose: ({sp[0]:.3f}, {sp[1]:.3f}, {sp[2]:.3f})")
    if summary.true_start is not None:
        ts = summary.true_start
        lines.append(f"true start pose:      ({ts[0]:.3f}, {ts[1]:.3f}, {ts[2]:.3f})")
    lines.append(
        f"landmarks {summary.landmarks_count}, predictions {summary.predictions}, "
        f"updates accepted {summary.accepted}, rejected {summary.rejected}, "
        f"refused {summary.refused}, initialised {summary.initialised}, "
        f"re-initialised {summary.reinitialised}"
    )
    if summary.ate_rmse is not None:
        lines.append(f"trajectory ATE RMSE (no alignment) {summary.ate_rmse:.3f} m")
    if "dropped" in out:
        lines.append(
            "dropped while loading: " + ", ".join(f"{k} {v}" for k, v in out["dropped"].items())
        )
    lines.append(f"replay {summary.seconds * 1e3:.1f} ms")
    if "plot" in out:
        lines.append(f"figure written to {out['plot']}")
    return "\n".join(lines)


def cmd_simulate(args: argparse.Namespace) -> int:
    from ekfslam.runlog import SIMULATED_DECIMALS, write_run
    from ekfslam.simulation import SimulationConfig, simulate

    kwargs = {"trajectory": args.trajectory, "laps": args.laps, "seed": args.seed}
    if args.size is not None:
        kwargs["size"] = args.size
    if args.start_error is not None:
        kwargs["start_error"] = tuple(args.start_error)
    if args.wheel_scale_sigma is not None:
        kwargs["wheel_scale_sigma"] = args.wheel_scale_sigma
    run = simulate(SimulationConfig(**kwargs))
    write_run(run, args.out, overwrite=args.overwrite, decimals=SIMULATED_DECIMALS)
    print(
        f"wrote {args.out}: {len(run.controls.t)} controls, {len(run.detections.t)} detections, "
        f"{run.controls.t[-1] - run.controls.t[0]:.1f} s"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except EkfSlamError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
