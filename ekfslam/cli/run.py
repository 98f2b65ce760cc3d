"""``python -m ekfslam run RUN``: replay a run and print its Table 1 row (eq. 17), or --json."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from typing import TYPE_CHECKING

from ekfslam import pipeline
from ekfslam.analysis import association as assoc
from ekfslam.analysis.association_auto import replay_auto
from ekfslam.analysis.evaluation import SEED_TABLE1, RunSummary, seed_experiment, summarize
from ekfslam.analysis.rescue import replay_rescued as rescued_replay
from ekfslam.cli import animate as animate_args
from ekfslam.cli import args as ca
from ekfslam.cli import team as team_cli
from ekfslam.cli.common import (
    add_founding_arguments,
    add_hypotheses_argument,
    add_iterations_argument,
    add_passes_argument,
    arena_half_size,
    load_run,
    noise_from_args,
    time_shared_of,
)
from ekfslam.core.association import METHODS
from ekfslam.core.recovery import RecoveryConfig
from ekfslam.files import save_figure
from ekfslam.logs.mrclam.defaults import MRCLAM_MAP_NOISE
from ekfslam.logs.mrclam.load import MrclamLoadReport
from ekfslam.logs.runlog import RunLog
from ekfslam.strategies import HiddenIds, KnownIds
from ekfslam.viz.tables import association_line, table1_lines

if TYPE_CHECKING:
    from ekfslam.core.noise import NoiseConfig
    from ekfslam.vision.frames_run import FramesReport


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``run`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    run = subparsers.add_parser(name, help=help)
    run.add_argument(
        "run", type=ca.given_path, help="a run folder (run.json ...) or a MRCLAM dataset folder"
    )
    ca.add_robot_argument(run)
    team_cli.add_team_argument(run)
    ca.add_replay_start_arguments(run)
    ca.add_plot_argument(run, "write the seed's Figure 2 for the run to FILE")
    animate_args.add_animate_arguments(run)
    ca.add_json_argument(run)
    run.add_argument(
        "--align",
        choices=["mean_distance", "least_squares"],
        default="mean_distance",
        help="eq. (17) objective: mean distance (the seed's) or least squares",
    )
    run.add_argument(
        "--association",
        choices=(*METHODS, "auto"),
        default="known",
        help="which landmark each sighting is: the detections' ids (known, the default), or, "
        "with the ids hidden from the filter, auto (the choice with hidden ids, what --hide-ids "
        "gives: jcbb, and mht only where jcbb's map is not to be trusted by its diagnosis; the "
        "output says which and why), nearest neighbour (nn), joint compatibility "
        "branch and bound (jcbb), or a bank of JCBB hypotheses that delays the decisions (mht); "
        "eq. (17) then matches landmarks through the estimated-to-true "
        "mapping. A MRCLAM run then replays with its noise tuned for consistency (the "
        "association trusts the filter's covariance), with each image's time stamp 0.2 s uncertain "
        "(one error shared by its sightings)",
    )
    run.add_argument(
        "--match",
        choices=tuple(assoc.MATCHINGS),
        default="mapping",
        help="with --association nn|jcbb|mht, how eq. (17) pairs estimated with true landmarks: "
        "through the association's mapping (the default), or by position (nearest neighbour "
        "after a robust fit, as for sightings without true ids)",
    )
    run.add_argument(
        "--hide-ids",
        action="store_true",
        help="hide the detections' ids from the filter: --association auto unless another "
        "method is named",
    )
    add_hypotheses_argument(run)
    run.add_argument(
        "--map-noise",
        choices=("auto", "none", "mrclam"),
        default="auto",
        help="with --association nn|jcbb|mht: feed the decisions as ids to a second filter that "
        "maps with this noise (mrclam: MRCLAM's consistency noise with sigma_x = sigma_y = "
        "0.005); none: the deciding filter maps; auto (the default): the data source's choice, "
        "as score-mrclam makes it (mrclam for MRCLAM runs, none for the others)",
    )
    add_passes_argument(run)
    add_founding_arguments(run)
    run.add_argument(
        "--noise",
        choices=("auto", "documented", "fit"),
        default="auto",
        help="auto (the default): the run's documented noise, and when the replay does not agree "
        "with its data (its diagnosis is not ok), R scaled by 2-16, the most likely; "
        "documented: exactly the documented noise (with the --sigma-* overrides, which auto "
        "also takes as they are); fit: fit R and Q to this run's innovations first, by maximum "
        "likelihood with no ground truth (as `fit-noise` does), starting from auto's result, and "
        "replay with them unless they replay less likely or with a worse diagnosis than auto's "
        "(then auto's is kept, and the output says so)",
    )
    run.add_argument(
        "--recover",
        action="store_true",
        help="with the ids known: after 20 rejected sightings in a row (of 2 or more landmarks) "
        "widen the pose covariance by what their innovations say, so a robot whose pose was "
        "lost relocalises against its map; the diagnosis lists when (off by default: on MRCLAM "
        "it helped as often as it hurt)",
    )
    run.add_check(_match_needs_hidden_ids)
    ca.add_noise_arguments(run)
    add_iterations_argument(run)
    run.set_defaults(func=cmd_run)


#: ``--map-noise``: the mapping filter's noise (`ekfslam.pipeline.replay`'s ``map_noise``).
MAP_NOISES = {"none": None, "mrclam": MRCLAM_MAP_NOISE}


def _map_noise(run: RunLog, choice: str) -> NoiseConfig | None:
    """``--map-noise``: auto is the data source's (`association_map_noise`), else the named one."""
    return assoc.association_map_noise(run) if choice == "auto" else MAP_NOISES[choice]


def _match_needs_hidden_ids(args: argparse.Namespace) -> str | None:
    if getattr(args, "hide_ids", False) and args.association == "known":
        args.association = "auto"  # --hide-ids: auto unless a method is named
    if args.association == "auto" and args.passes != 1:
        return "argument --passes: auto chooses its replays; name a method (jcbb, nn or mht)"
    if args.match != "mapping" and args.association == "known":
        return "argument --match: needs --association nn, jcbb or mht (known ids match by id)"
    if args.hypotheses is not None and args.association != "mht":
        return "argument --hypotheses: only with --association mht"
    if args.map_noise != "auto" and args.association == "known":
        return "argument --map-noise: needs --association nn, jcbb or mht"
    if args.time_error is not None and args.association == "known":
        return "argument --time-error: needs --association nn, jcbb or mht"
    if args.new_rule is not None and args.association not in ("jcbb", "mht"):
        return "argument --new-rule: needs --association jcbb or mht"
    if args.passes != 1 and args.association == "known":
        return "argument --passes: needs --association nn, jcbb or mht"
    if getattr(args, "recover", False) and args.association != "known":
        return "argument --recover: needs the ids known (not with --association)"
    if getattr(args, "noise", "auto") == "fit" and args.association != "known":
        return "argument --noise fit: fits with the known ids; not with --association"
    if args.passes != 1 and getattr(args, "linearization", None) == "invariant":
        return "argument --passes: needs the standard or fej filter, not --linearization invariant"
    return None


def cmd_run(args: argparse.Namespace) -> int:
    if getattr(args, "robots", None):  # a team: its robots in one joint filter
        return team_cli.cmd_team(args)
    run, report = load_run(args)
    hidden = getattr(args, "association", "known") != "known"
    # with the ids hidden, a noise whose Σ the association's χ² tests can trust
    noise, config = noise_from_args(args, run, assoc.association_noise(run) if hidden else None)
    fitted = rescue = chosen = None
    if getattr(args, "noise", "auto") == "fit":
        # lazy: scipy.optimize (about 0.3 s) only when asked to fit
        # the fit starts from the rescued default and is kept only when it replays no worse
        fitted = importlib.import_module("ekfslam.analysis.noise_fit").fit_from_default(
            run, noise, config
        )
        noise, config = fitted.noise, fitted.result.config
    animate = getattr(args, "animate", None)
    recovering = getattr(args, "recover", False)
    recover = {"association": KnownIds(recovery=RecoveryConfig())} if recovering else {}
    # only an animation needs copies of the whole state (`Keyframes`); a plain replay keeps none
    frames = (
        {"keyframes": args.frames or animate_args.DEFAULT_FRAMES} if animate is not None else {}
    )
    # looked up here: tests may replace it (and, with known ids, call it as before)
    if hidden and args.association == "auto":  # jcbb, escalated where it is not to be trusted
        chosen = replay_auto(
            run,
            noise,
            config,
            map_noise=_map_noise(run, getattr(args, "map_noise", "auto")),
            time_shared=time_shared_of(args),
            **frames,
        )
        association = assoc.association_config(
            run, chosen.strategy.method, chosen.strategy.hypotheses, time_shared_of(args)
        )
        result, found = assoc.score(run, chosen.result, args.match)
        labels = None if animate is None else animate_args.true_labels(result, found.mapping)
    elif hidden:
        association = assoc.association_config(
            run,
            args.association,
            args.hypotheses,
            time_shared_of(args),
            getattr(args, "new_rule", None),
        )
        result = pipeline.replay(
            run,
            noise,
            config,
            association=HiddenIds(
                association,
                passes=getattr(args, "passes", 1),
                map_noise=_map_noise(run, getattr(args, "map_noise", "auto")),
            ),
            **frames,
        )
        result, found = assoc.score(run, result, args.match)
        labels = None if animate is None else animate_args.true_labels(result, found.mapping)
    elif fitted is not None:  # the kept replay (the fit's, or the rescued default's)
        result, labels = fitted.result, None
        if frames or recover:
            result = pipeline.replay(run, noise, config, **frames, **recover)
    elif _rescues(args):  # the documented noise, or R scaled when it does not fit the log
        rescue = rescued_replay(run, noise, config, **frames, **recover)
        result, labels = rescue.result, None
    else:
        result = pipeline.replay(run, noise, config, **frames, **recover)
        labels = None
    summary = summarize(run, result, method=args.align)
    out = summary.as_dict()
    if hidden:
        out["association"] = assoc.as_dict(result, found, args.match, association)
    if chosen is not None:
        out["association"]["auto"] = chosen.as_dict()
    if result.passes:  # --passes N > 1: which pass the map is, and what each one changed
        out["passes"] = {
            "chosen": result.chosen_pass,
            "each": [{"cost": p.cost, "changed": p.changed} for p in result.passes],
        }
    if fitted is not None:
        out["noise_fit"] = fitted.as_dict()
    if rescue is not None and len(rescue.tried) > 1:  # the documented noise was not ok
        out["noise_rescue"] = rescue.as_dict()
    out["seed_report"] = _seed_report(run)
    out["detections"] = _detections_source(run, report)
    if report is not None:
        loading = report.as_dict()
        out["loaded"], out["dropped"] = loading["loaded"], loading["dropped"]
    if args.plot is not None:
        # matplotlib (about 0.3 s) only for a figure: a plain replay stays fast to start
        plotting = importlib.import_module("ekfslam.viz.plotting")
        fig = plotting.figure2(
            run,
            result,
            arena_half_size=arena_half_size(run),
            alignment=summary.alignment,
            alignment_note=summary.alignment_note,
        )
        out["plot"] = str(save_figure(fig, args.plot))
    if animate is not None:
        out["animation"], out["animation_frames"] = animate_args.write_animation(
            run, result, animate, args.fps, labels
        )
    if args.json:
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        if fitted is not None:
            print("\n".join(["noise fitted to the run's innovations:", *fitted.fit.lines()]))
            print(fitted.line())
        print(_table(summary, out, report))
        if rescue is not None and rescue.line() is not None:
            print(rescue.line())
        if chosen is not None:
            print(chosen.line())
    warning = None if result.diagnosis is None else result.diagnosis.warning()
    if warning is not None:  # a replay that does not agree with its data says so, always
        print(f"warning: {warning}", file=sys.stderr)
    return 0


#: The noise options a rescue leaves as given (`_rescues`).
_SIGMAS = ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")


def _rescues(args: argparse.Namespace) -> bool:
    """``--noise auto`` with the documented noise as it is: no ``--sigma-*`` given (those are
    replayed exactly as asked, the diagnosis saying whether they fit)."""
    return getattr(args, "noise", "auto") == "auto" and all(
        getattr(args, name, None) is None for name in _SIGMAS
    )


def _true_labels(result: pipeline.ReplayResult, mapping: dict[int, int]) -> list[str]:
    """Each landmark slot's true id: with hidden ids the filter names its landmarks 0, 1, ..."""
    assert result.keyframes is not None  # asked for with --animate
    return [str(mapping[e]) if e in mapping else f"new {e}" for e in result.keyframes.landmark_ids]


def _seed_report(run: RunLog) -> dict | None:
    """The seed's Table 1 row (real robot) when `run` is the seed's experiment, else None.

    Judged by run.json's ``simulation`` block (`ekfslam.analysis.evaluation.seed_experiment`), not
    by the run's name: a square of another seed or size is not the run the seed measured.
    """
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


def _detections_source(run: RunLog, report: FramesReport | MrclamLoadReport | None) -> str:
    """Which detections a replay used: detected from frames now, or read from which file."""
    if isinstance(report, MrclamLoadReport):
        return f"Robot{report.robot}_Measurement.dat"
    if report is not None:  # `load_run` reports only for MRCLAM and for frames detected now
        return "frames (detected now)"
    if run.meta.frames is not None:  # `detect --in-place` wrote it: the frames are not looked at
        return "detections.csv (not the run's frames; delete it to detect from them)"
    return "detections.csv"


def _table(summary: RunSummary, out: dict, report=None) -> str:
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
    if summary.diagnosis is not None:
        lines.append(summary.diagnosis.line())
    if summary.ate_rmse is not None:
        lines.append(f"trajectory ATE RMSE (no alignment) {summary.ate_rmse:.3f} m")
    elif summary.ate_note is not None:
        lines.append(f"trajectory ATE RMSE: none, {summary.ate_note}")
    if "association" in out:
        lines.append(association_line(out["association"]))
    if "passes" in out:
        each = out["passes"]["each"]
        changed = ", ".join(str(p["changed"]) for p in each[1:])
        lines.append(
            f"passes: the map of pass {out['passes']['chosen']} of {len(each)} (decisions "
            f"changed per pass: {changed})"
        )
    if "detections" in out:
        lines.append(f"detections: {out['detections']}")
    if report is not None:  # a loader's report: what it read, and what it dropped and why
        lines += report.lines()
    lines.append(f"replay {summary.seconds * 1e3:.1f} ms")
    if "plot" in out:
        lines.append(f"figure written to {out['plot']}")
    if "animation" in out:
        lines.append(f"animation written to {out['animation']} ({out['animation_frames']} frames)")
    return "\n".join(lines)
