"""The command line: ``python -m ekfslam run|simulate|fetch ...``.

Bad input ends with one line on stderr that names the file, the line and the problem, and exit
status 2; never a traceback. A bad option value or output path is refused the same way while
the command line is parsed, before any work (the types and checks are in `ekfslam.cli.args`).
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import warnings
from pathlib import Path

from ekfslam.analysis.evaluation import SEED_TABLE1
from ekfslam.cli import args as ca
from ekfslam.errors import ConfigError, EkfSlamError, InputError
from ekfslam.files import save_figure
from ekfslam.viz.tables import table1_lines

EXIT_BAD_INPUT = 2

#: Upper bounds of the noise options: beyond them σ² dt, and Σ, lose every digit of the poses.
MAX_MOTION_SIGMA = 10.0  # m/√s and rad/√s
MAX_RANGE_SIGMA = 100.0  # m
#: The simulated path must stay this far inside the seed's arena walls (m).
ARENA_MARGIN = 0.05
#: Laps: 100 laps of the largest square take about 4500 s, within the controller's 10^4 s.
MAX_LAPS = 100
ROBOTS = range(1, 6)

#: Modules with an ``add_cli(subparsers)`` that registers a subcommand (``set_defaults(func=...)``).
_COMMAND_MODULES: tuple[str, ...] = (
    "ekfslam.logs.mrclam.fetch",
    "ekfslam.logs.mrclam.load",
    "ekfslam.logs.rosbag",
    "ekfslam.logs.tum",
    "ekfslam.logs.frames",
    "ekfslam.analysis.vision_eval",
    "ekfslam.analysis.consistency",
    "ekfslam.analysis.bench",
)


def add_noise_arguments(p: argparse.ArgumentParser) -> None:
    from ekfslam.core.filter.ekf import CHI2_2DOF_99

    g = p.add_argument_group("noise (R, eq. 9, and Q, eq. 11) and filter options")
    motion = ca.non_negative(MAX_MOTION_SIGMA, why="larger noise swamps every pose")
    g.add_argument("--sigma-x", type=motion, help="motion noise along the body x axis, m/√s")
    g.add_argument("--sigma-y", type=motion, help="motion noise along the body y axis, m/√s")
    g.add_argument("--sigma-theta", type=motion, help="heading noise, rad/√s")
    g.add_argument(
        "--sigma-range", type=ca.positive(MAX_RANGE_SIGMA, why="m"), help="range noise σ_r, m"
    )
    g.add_argument(
        "--sigma-bearing", type=ca.positive(math.pi, why="π rad"), help="bearing noise σ_φ, rad"
    )
    g.add_argument(
        "--init", choices=["inverse", "seed"], default="inverse",
        help="landmark initialisation: inverse observation (default) or the seed's eq. (3)",
    )  # fmt: skip
    g.add_argument(
        "--gate", type=ca.non_negative(1e6), default=CHI2_2DOF_99,
        help="NIS gate (chi-square, 2 dof); 0 turns gating off (default: %(default).2f)",
    )  # fmt: skip
    g.add_argument(
        "--reinit-after", type=ca.whole(2, 10**6, also=(0,)),
        help="re-initialise a landmark after this many agreeing rejected sightings; 0: never "
        "(default: 3, but never for MRCLAM)",
    )  # fmt: skip


def build_parser() -> argparse.ArgumentParser:
    parser = ca.Parser(
        prog="python -m ekfslam",
        description="Landmark EKF SLAM after the UCSD CSE276A HW3 report.",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ca.Parser)

    run = sub.add_parser("run", help="replay a run (our run-log folder, or a MRCLAM dataset)")
    run.add_argument(
        "run", type=Path, help="a run folder (run.json ...) or a MRCLAM dataset folder"
    )
    add_robot_argument(run)
    add_plot_argument(run, "write the seed's Figure 2 for the run to FILE")
    run.add_argument("--json", action="store_true", help="print one JSON object")
    run.add_argument(
        "--align", choices=["mean_distance", "least_squares"], default="mean_distance",
        help="eq. (17) objective: mean distance (the seed's) or least squares",
    )  # fmt: skip
    add_noise_arguments(run)
    run.set_defaults(func=cmd_run)

    sim = sub.add_parser("simulate", help="simulate the seed's robot and write a run folder")
    sim.add_argument("--trajectory", choices=["square", "octagon"], required=True)
    sim.add_argument("--laps", type=ca.whole(1, MAX_LAPS, why="the controller's time limit"),
                     default=2, help=f"laps, 1 to {MAX_LAPS} (default: %(default)s)")  # fmt: skip
    sim.add_argument(
        "--size", type=ca.positive(),
        help="side of the square / size of the octagon, m; the path must stay "
        f"{ARENA_MARGIN * 100:.0f} cm inside the seed's arena",
    )  # fmt: skip
    sim.add_argument("--seed", type=ca.seed(), default=1)
    sim.add_argument(
        "--start-error", type=ca.finite(), nargs=3, metavar=("DX", "DY", "DTHETA"),
        help="the robot's true placement error, m, m, rad, within ±0.5 m and ±π "
        "(default: drawn from the seed)",
    )  # fmt: skip
    sim.add_argument(
        "--wheel-scale-sigma", type=ca.non_negative(0.3, why="a 3σ scale must stay positive"),
        help="std of a per-wheel calibration error (a fraction; default 0: none)",
    )  # fmt: skip
    add_run_folder_arguments(sim)
    sim.add_check(_check_path_in_arena)
    sim.add_check(triple_check("--start-error", (0.5, 0.5, math.pi), ("DX", "DY", "DTHETA")))
    sim.set_defaults(func=cmd_simulate)

    # Commands that live with their concept: each module adds its own subparser.
    for module in _COMMAND_MODULES:
        importlib.import_module(module).add_cli(sub)
    return parser


def add_robot_argument(p: argparse.ArgumentParser) -> None:
    """``--robot N`` for commands that read MRCLAM datasets (their robots are 1-5)."""
    p.add_argument(
        "--robot", type=ca.one_of(ROBOTS, "MRCLAM robots"), help="MRCLAM only: which robot (1-5)"
    )


def add_plot_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--plot FILE``: checked before the work; the suffix names the format and is required."""
    p.add_argument(
        "--plot", type=ca.output_file(ca.PLOT_FORMATS), metavar="FILE",
        help=f"{what}; FILE must end in {', '.join(ca.PLOT_FORMATS)} (no extension is added); "
        "missing folders are created",
    )  # fmt: skip


def add_run_folder_arguments(p: argparse.ArgumentParser, required: bool = True) -> None:
    """``--out DIR --overwrite`` for commands that write a run folder, checked before the work."""
    p.add_argument("--out", type=ca.output_folder, required=required, metavar="DIR",
                   help="the run folder to write (created if missing)")  # fmt: skip
    p.add_argument("--overwrite", action="store_true", help="replace an existing run folder")
    p.add_check(ca.new_run_folder("--out"))


def triple_check(option: str, bounds: tuple[float, float, float], names: tuple[str, ...]):
    """A parser check: each of the 3 values of `option` lies within ±its bound."""
    dest = option.lstrip("-").replace("-", "_")

    def check(args: argparse.Namespace) -> str | None:
        values = getattr(args, dest, None)
        if values is None:
            return None
        for name, value, bound in zip(names, values, bounds, strict=True):
            if abs(value) > bound:
                return f"argument {option}: {name} must be within ±{bound:.4g}, got {value:g}"
        return None

    return check


def _check_path_in_arena(args: argparse.Namespace) -> str | None:
    """The simulated path must stay inside the seed's arena, whose walls hold every tag."""
    from ekfslam.core.arena import SEED_ARENA

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


def load_run(args: argparse.Namespace):
    """A RunLog from either format, plus a note on anything the loader dropped.

    The format is what the folder holds: run.json is our run format; Barcodes.dat, or any of
    MRCLAM's other files (Landmark_Groundtruth.dat, RobotN_*.dat), a MRCLAM dataset.
    """
    folder: Path = args.run
    if not folder.is_dir():
        problem = "is not a folder" if folder.exists() else "run folder not found"
        raise InputError(folder, None, f"{problem}; give a run folder or a MRCLAM dataset folder")
    ours = (folder / "run.json").exists() or (folder / "run.json").is_symlink()
    mrclam = (folder / "Barcodes.dat").exists() or (
        not ours
        and ((folder / "Landmark_Groundtruth.dat").exists() or any(folder.glob("Robot*_*.dat")))
    )
    if mrclam:
        from ekfslam.logs.mrclam.load import BARCODES, load_mrclam

        if not (folder / BARCODES).is_file():
            raise InputError(
                folder / BARCODES, None, "missing file; this MRCLAM dataset folder needs it"
            )
        if args.robot is None:
            raise InputError(folder, None, "a MRCLAM dataset needs --robot N (1-5)")
        run, report = load_mrclam(folder, args.robot)
        return run, report
    if args.robot is not None:
        raise InputError(folder, None, "--robot is only for MRCLAM datasets (no Barcodes.dat)")
    if not ours and not any((folder / name).exists() for name in ("controls.csv", "frames.csv")):
        raise InputError(
            folder, None, "no run.json (our run format) and no Barcodes.dat (MRCLAM) in this folder"
        )
    # A run logged as camera frames, with no detections.csv yet: detect the tags in its frames.
    from ekfslam.logs.frames import has_frames_only
    from ekfslam.vision.frames_run import read_frames_run

    if has_frames_only(folder):
        return read_frames_run(folder)
    from ekfslam.logs.runlog import read_run

    return read_run(folder), None


def noise_from_args(args: argparse.Namespace, run):
    from dataclasses import replace

    from ekfslam.core.noise import NoiseConfig, default_config, default_noise

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
    from ekfslam.analysis.evaluation import summarize
    from ekfslam.pipeline import replay

    run, report = load_run(args)
    noise, config = noise_from_args(args, run)
    result = replay(run, noise, config)
    summary = summarize(run, result, method=args.align)
    out = summary.as_dict()
    out["seed_report"] = _seed_report(run)
    out["detections"] = _detections_source(run, report)
    if report is not None:
        loading = report.as_dict()
        out["loaded"], out["dropped"] = loading["loaded"], loading["dropped"]
    if args.plot is not None:
        from ekfslam.viz.plotting import figure2

        fig = figure2(
            run, result, arena_half_size=_arena_half_size(run), alignment=summary.alignment,
            alignment_note=summary.alignment_note,
        )  # fmt: skip
        out["plot"] = str(save_figure(fig, args.plot))
    if args.json:
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        print(_table(summary, out, report))
    return 0


def _arena_half_size(run) -> float | None:
    """The seed's arena walls are drawn when the run's tag map is the seed's."""
    from ekfslam.core.arena import SEED_ARENA

    tags = run.meta.tag_map or {}
    seed = SEED_ARENA.tag_map()
    same = tags.keys() == seed.keys() and all(
        abs(tags[i][0] - seed[i][0]) < 1e-9 and abs(tags[i][1] - seed[i][1]) < 1e-9 for i in seed
    )
    return SEED_ARENA.half_size if same else None


def _seed_report(run) -> dict | None:
    """The seed's Table 1 row (real robot) when `run` is the seed's experiment, else None.

    Judged by run.json's ``simulation`` block (`ekfslam.analysis.evaluation.seed_experiment`), not
    by the run's name: a square of another seed or size is not the run the seed measured.
    """
    from ekfslam.analysis.evaluation import seed_experiment

    trajectory = seed_experiment(run.meta.simulation)
    if trajectory is None:
        return None
    x0, y0, theta0, mean_error = SEED_TABLE1[trajectory]
    return {
        "trajectory": trajectory,
        "x0": x0,
        "y0": y0,
        "theta0": theta0,
        "mean_error": mean_error,
    }


def _detections_source(run, report) -> str:
    """Which detections a replay used: detected from frames now, or read from which file."""
    from ekfslam.logs.mrclam.load import MrclamLoadReport
    from ekfslam.vision.frames_run import FramesReport

    if isinstance(report, FramesReport):
        return "frames (detected now)"
    if isinstance(report, MrclamLoadReport):
        return f"Robot{report.robot}_Measurement.dat"
    if run.meta.frames is not None:  # `detect --in-place` wrote it: the frames are not looked at
        return "detections.csv (not the run's frames; delete it to detect from them)"
    return "detections.csv"


def _table(summary, out: dict, report=None) -> str:
    a = summary.alignment
    seed = out.get("seed_report")  # only for a replay of the seed's own experiment (cmd_run)
    row = None
    if seed is not None and a is not None:
        row = (seed["x0"], seed["y0"], seed["theta0"], seed["mean_error"])
    lines = table1_lines(summary, row)
    if a is not None:
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
        + (f", singular S {summary.singular}" if summary.singular else "")
    )
    if summary.ate_rmse is not None:
        lines.append(f"trajectory ATE RMSE (no alignment) {summary.ate_rmse:.3f} m")
    if "detections" in out:
        lines.append(f"detections: {out['detections']}")
    if report is not None:  # a loader's report: what it read, and what it dropped and why
        lines += report.lines()
    lines.append(f"replay {summary.seconds * 1e3:.1f} ms")
    if "plot" in out:
        lines.append(f"figure written to {out['plot']}")
    return "\n".join(lines)


def cmd_simulate(args: argparse.Namespace) -> int:
    from ekfslam.logs.runlog import SIMULATED_DECIMALS, write_run
    from ekfslam.sim.simulation import SimulationConfig, simulate

    kwargs = {"trajectory": args.trajectory, "laps": args.laps, "seed": args.seed}
    if args.size is not None:
        kwargs["size"] = args.size
    if args.start_error is not None:
        kwargs["start_error"] = tuple(args.start_error)
    if args.wheel_scale_sigma is not None:
        kwargs["wheel_scale_sigma"] = args.wheel_scale_sigma
    run = simulate(SimulationConfig(**kwargs))
    write_run(
        run, args.out, overwrite=args.overwrite, overwrite_hint="--overwrite",
        decimals=SIMULATED_DECIMALS,
    )  # fmt: skip
    print(
        f"wrote {args.out} ({run.meta.name}): {len(run.controls.t)} controls, "
        f"{len(run.detections.t)} detections, "
        f"{run.controls.t[-1] - run.controls.t[0]:.1f} s of simulated time"
    )
    return 0


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning on the command line is one line that says what happened, not where in our code."""
    print(f"warning: {' '.join(str(message).split())}", file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns its exit status (2: a bad option, path or input, one line)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)  # a bad option ends here, before any work
    except SystemExit as exc:  # --help (0) or a refused option (2): a status, as for the rest
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return args.func(args)
    except BrokenPipeError:  # `... | head` closed our stdout: not an error of ours
        # Python would complain again when it flushes stdout at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (InputError, ConfigError) as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except EkfSlamError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
