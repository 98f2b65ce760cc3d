"""``python -m ekfslam run DATASET --robots all`` (or ``--robots 1 3 5``): a MRCLAM dataset's
robots replayed through one joint filter (`ekfslam.team.replay_team`).

Prints the joint map's Table 1 row (eq. 17 against the true landmarks) and, per robot, how it
entered the map (at its start, from its own map's landmarks, or from its sightings with robots
already placed: `ekfslam.team`), its trajectory error against Vicon where there is one, the
sightings it used (landmarks, robots) and its diagnosis, a single replay's
(`ekfslam.core.diagnosis`: does its replay agree with its data; a robot that does not says so on
stderr, as ``run`` does), with whether its filter lost it at the end and how often recovery
widened its pose; ``--json`` carries the same, ``--plot FILE`` draws the robots' trajectories
and the one map.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from pathlib import Path

import numpy as np

from ekfslam.analysis import association as assoc
from ekfslam.analysis.alignment import align
from ekfslam.analysis.alignment_unlabelled import match_by_position
from ekfslam.analysis.evaluation import interpolate_poses
from ekfslam.cli import args as ca
from ekfslam.cli.common import time_shared_of
from ekfslam.errors import InputError
from ekfslam.files import save_figure
from ekfslam.logs.mrclam.load import BARCODES, ROBOTS, find_dataset
from ekfslam.logs.mrclam.team import load_mrclam_team
from ekfslam.team import TeamResult, replay_team
from ekfslam.viz.tables import COMMAND_LINE, table1_row


def robots_argument(text: str) -> str | int:
    """``all`` or a robot's number (1-5), for ``--robots``."""
    if text == "all":
        return text
    return ca.one_of(ROBOTS, "MRCLAM robots")(text)


def add_team_argument(p: argparse.ArgumentParser) -> None:
    """``--robots all | N [N ...]``: replay these robots together, in one map."""
    p.add_argument(
        "--robots",
        nargs="+",
        type=robots_argument,
        metavar="N",
        help="MRCLAM only: replay these robots (all, or numbers 1-5) together in one joint "
        "filter, each robot's sightings of the others correcting both poses; prints the joint "
        "map's Table 1 row and each robot's entry, trajectory error and sightings; with "
        "--hide-ids the landmarks' ids are hidden (each robot's sightings associated against "
        "the joint map by jcbb, or --association nn) while the robots' barcodes stay known: "
        "they name robots, not landmarks",
    )


def chosen_robots(folder: Path, values: list) -> tuple[int, ...]:
    """The robots ``--robots`` names: all five for ``all``; each number once."""
    if "all" in values:
        if len(values) > 1:
            raise InputError(folder, None, "--robots: give all, or robot numbers, not both")
        return ROBOTS
    twice = sorted({v for v in values if values.count(v) > 1})
    if twice:
        raise InputError(folder, None, f"--robots: robot {twice[0]} is named twice")
    return tuple(sorted(values))


def cmd_team(args: argparse.Namespace) -> int:
    """The team replay of ``run DATASET --robots ...``."""
    for option, default in (("noise", "auto"), ("animate", None)):
        if getattr(args, option, default) != default:
            name = option.replace("_", "-")
            raise InputError(
                args.run,
                None,
                f"--{name} is not available with --robots yet (a team replays with each "
                "robot's documented noise)",
            )
    method = getattr(args, "association", "known")
    if method == "mht":
        raise InputError(
            args.run,
            None,
            "--association mht is not available with --robots (a team associates with nn or "
            "jcbb; --hide-ids gives jcbb)",
        )
    if getattr(args, "robot", None) is not None:
        raise InputError(args.run, None, "give --robot N (one robot) or --robots (a team)")
    folder = _dataset_folder(args.run)
    team, report = load_mrclam_team(
        folder, chosen_robots(folder, args.robots), max_range=getattr(args, "max_range", None)
    )
    if method == "known":
        result, config = replay_team(team), None
    else:  # --hide-ids is auto: jcbb (a team has no mht to escalate to)
        first = team.runs[team.robots[0]]
        config = assoc.association_config(
            first, "jcbb" if method == "auto" else method, time_shared=time_shared_of(args)
        )
        noise = {robot: assoc.association_noise(run) for robot, run in team.runs.items()}
        mapping = {robot: assoc.association_map_noise(run) for robot, run in team.runs.items()}
        result = replay_team(
            team,
            noise,
            association=config,
            match_maps=match_by_position,
            map_noise=None if None in mapping.values() else mapping,
        )
    out = team_dict(team, result, report, config, getattr(args, "match", "mapping"))
    if args.plot is not None:
        # matplotlib only for a figure (about 0.3 s)
        plotting = importlib.import_module("ekfslam.viz.team_plot")
        fig = plotting.team_figure(team, result, _alignment(team, result, out))
        out["plot"] = str(save_figure(fig, args.plot))
    if args.json:
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        print(team_lines(out))
    for robot, r in out["robots"].items():  # a robot that does not agree with its data says so
        if r["diagnosis"]["warning"] is not None:
            print(f"warning: robot {robot}: {r['diagnosis']['warning']}", file=sys.stderr)
    return 0


def _dataset_folder(path: Path) -> Path:
    folder = Path(path)
    if not folder.exists() and str(folder).isdigit() and int(str(folder)) in ca.MRCLAM_DATASETS:
        folder = find_dataset(int(str(folder)))
    if not (folder / BARCODES).is_file():
        raise InputError(folder, None, f"--robots needs a MRCLAM dataset folder (no {BARCODES})")
    return folder


def _alignment(team, result: TeamResult, out: dict):
    """Eq. (17) of the joint map: by id, or, with hidden ids, through `score_team`."""
    landmarks = result.landmarks
    if "association" in out:
        landmarks = assoc.score_team(team, result, out["association"]["match"])[0]
    return align(landmarks, team.tag_map)


def team_dict(team, result: TeamResult, report, config=None, match: str = "mapping") -> dict:
    """The JSON of a team replay: the joint map's alignment at the top level (as a single
    run's), ``robots`` keyed by number, ``seconds``, and what was loaded and dropped; with
    hidden ids (`config`, the `AssociationConfig`), ``association``: the decisions of every
    robot against the true ids (`ekfslam.analysis.association.score_team`) and their counts,
    the map scored as a single hidden-id run's is (through the decisions' mapping, or
    ``match`` "position")."""
    block = None
    if config is not None:
        landmarks, found = assoc.score_team(team, result, match)
        counts: dict[str, int] = {}
        for robot in result.robots:
            for name, n in (result.tracks[robot].association or {}).items():
                counts[name] = counts.get(name, 0) + n
        block = {
            "method": config.method,
            "match": match,
            "correct": found.correct,
            "wrong": found.wrong,
            "missed": found.missed,
            "correct_fraction": found.correct_fraction,
            "duplicates": len(found.duplicates),
            "landmarks_mapped": len(result.landmarks),
            "counts": counts,
            "time_error": {
                "sigma": config.time_sigma,
                "form": "shared" if config.time_shared else "independent",
            },
            "barcodes": "robots' barcodes known (they name robots, not landmarks)",
        }
        a = align(landmarks, team.tag_map)
    else:
        a = align(result.landmarks, team.tag_map)
    robots = {}
    for robot in result.robots:
        run, track, entry = team.runs[robot], result.tracks[robot], result.entries.get(robot)
        ate = None
        if run.groundtruth is not None and entry is not None:
            truth, inside = interpolate_poses(run.groundtruth, track.t)
            error = track.pose[inside, :2] - truth[inside, :2]
            ate = float(np.sqrt(np.mean(np.sum(error**2, axis=1)))) if inside.any() else None
        robots[str(robot)] = {
            "entry": None
            if entry is None
            else {
                "how": entry.how,
                "seconds": round(entry.seconds, 3),
                "landmarks": list(entry.landmarks),
                "robots": list(entry.robots),
                "robot_sightings": entry.sightings,
                "residual_m": entry.residual,
                "sigma": _entry_sigma(entry),
                "described": entry.describe(),
            },
            "trajectory": {
                "ate_rmse": ate,
                "reason": None if ate is not None else "no Vicon ground truth for this robot",
            },
            "sightings": {
                "landmarks": track.landmarks,
                "robots": track.robots_seen,
                "seen_by_others_accepted": track.seen_by,
                "alone_before_entering": track.alone,
                "skipped": track.skipped,
            },
            "diagnosis": _diagnosis(track, team.span()[0]),
        }
    return {
        "name": result.name,
        "alignment": {
            "x0": a.x0,
            "y0": a.y0,
            "theta0": a.theta0,
            "mean_error": a.mean_error,
            "rmse": a.rmse,
            "landmarks_matched": len(a.ids),
        },
        **({"association": block} if block is not None else {}),
        "robots": robots,
        "seconds": result.seconds,
        "loaded": report.as_dict(),
    }


def _entry_sigma(entry) -> dict | None:
    """The σ of a robot's pose as it entered (m, m, rad), or None where it is not known."""
    sigma = np.sqrt(np.clip(np.diag(entry.covariance), 0.0, None))
    if not np.all(np.isfinite(sigma)):
        return None
    return {"x": float(sigma[0]), "y": float(sigma[1]), "theta": float(sigma[2])}


def _diagnosis(track, t0: float) -> dict:
    """A robot's ``diagnosis`` block: a single replay's (`ekfslam.core.diagnosis.Diagnosis`,
    its times from the robot's first control), its one line and warning, when recovery widened
    its pose (s on the team's clock) and whether its last sightings were all rejected (then its
    verdict is "lost" whatever the figures say)."""
    d = track.diagnosis
    out = d.as_dict()
    out["recoveries_s"] = [round(t - t0, 3) for t in track.recoveries]
    out["lost_at_end"] = track.lost_at_end
    if track.lost_at_end:
        out["verdict"] = "lost"
    out["line"] = d.line()
    out["warning"] = d.warning() or (LOST_AT_END if track.lost_at_end else None)
    return out


#: What a robot whose last sightings were all rejected says (`_diagnosis`).
LOST_AT_END = (
    "lost: its last 20 landmark sightings were all rejected; its final pose is not to be trusted"
)


def team_lines(out: dict) -> str:
    """The terminal's table: the joint map's Table 1 row, then a line per robot."""
    layout = COMMAND_LINE
    n = layout.number
    a = out["alignment"]
    head = (
        f"{'Map':<{layout.name}}{'x0':>{n}}{'y0':>{n}}{'theta0':>{n}}"
        f"{layout.error_title:>{layout.error}}"
    )
    row = table1_row(out["name"], (a["x0"], a["y0"], a["theta0"], a["mean_error"]), layout)
    lines = [head, row, ""]
    if "association" in out:
        b = out["association"]
        lines[-1:] = [
            f"landmark ids hidden ({b['method']}; the robots' barcodes known): "
            f"{b['correct']} sightings paired right, {b['wrong']} wrong, {b['missed']} missed; "
            f"{b['landmarks_mapped']} landmarks in the joint map; {b['duplicates']} landmarks "
            "(the robots' own maps counted) founded for a tag another already stood for",
            "",
        ]
    for robot, r in out["robots"].items():
        entry = r["entry"]["described"] if r["entry"] else NEVER
        ate = r["trajectory"]["ate_rmse"]
        s = r["sightings"]
        lines.append(
            f"robot {robot}: entered {entry}; trajectory error "
            + (f"{ate:.3f} m" if ate is not None else "n/a (no Vicon)")
            + f"; landmark sightings {_counts(s['landmarks'])}; robot sightings "
            f"{_counts(s['robots'])}; {r['diagnosis']['verdict']}"
            + (
                f" ({len(r['diagnosis']['recoveries_s'])} recoveries)"
                if r["diagnosis"]["recoveries_s"]
                else ""
            )
        )
        lines.append(f"  {r['diagnosis']['line']}")
    lines.append(f"{len(out['robots'])} robots in {out['seconds']:.1f} s")
    return "\n".join(lines)


#: Why a robot never entered the joint map.
NEVER = (
    "never: its own map did not share 3 landmarks, spread 1 m or more, with the joint map, nor "
    "did its sightings with placed robots fix its pose"
)


def _counts(counts: dict) -> str:
    if not counts:
        return "none"
    return ", ".join(f"{n} {label}" for label, n in sorted(counts.items()))
