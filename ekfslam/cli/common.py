"""What the commands that replay a run share: the run from either format, and its noise.

``run`` and ``tum`` take the same RUN argument (our run folder, a run of camera frames, or a
MRCLAM dataset folder with ``--robot``) and the same noise options (`args.add_noise_arguments`).
"""

from __future__ import annotations

import argparse
import importlib
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ekfslam.cli import args as ca
from ekfslam.core.arena import SEED_ARENA
from ekfslam.core.association import NEW_RULES, AssociationConfig
from ekfslam.core.filter.config import MAX_PASSES, FilterConfig
from ekfslam.core.noise import NoiseConfig, default_config, default_noise
from ekfslam.errors import InputError
from ekfslam.files import not_a_file
from ekfslam.logs.frames import has_frames_only
from ekfslam.logs.mrclam.load import BARCODES, MrclamLoadReport, find_dataset, load_mrclam
from ekfslam.logs.runlog import RunLog, read_run

if TYPE_CHECKING:
    from ekfslam.vision.frames_run import FramesReport


def mrclam_folder(dataset: Path | int) -> Path:
    """The folder of a dataset named by `ekfslam.cli.args.mrclam_dataset` (a folder or 1-9)."""
    return find_dataset(dataset) if isinstance(dataset, int) else dataset


def load_run(args: argparse.Namespace) -> tuple[RunLog, FramesReport | MrclamLoadReport | None]:
    """A RunLog from either format, plus a note on anything the loader dropped.

    The format is what the folder holds: run.json is our run format; Barcodes.dat, or any of
    MRCLAM's other files (Landmark_Groundtruth.dat, RobotN_*.dat), a MRCLAM dataset.
    """
    folder: Path = args.run
    if not folder.exists() and str(folder).isdigit() and int(str(folder)) in ca.MRCLAM_DATASETS:
        folder = find_dataset(int(str(folder)))  # `run 7 --robot 1`: MRCLAM Dataset 7
    if not folder.is_dir():
        problem = "is not a folder" if folder.exists() else "run folder not found"
        raise InputError(folder, None, f"{problem}; give a run folder or a MRCLAM dataset folder")
    ours = (folder / "run.json").exists() or (folder / "run.json").is_symlink()
    mrclam = (folder / "Barcodes.dat").exists() or (
        not ours
        and ((folder / "Landmark_Groundtruth.dat").exists() or any(folder.glob("Robot*_*.dat")))
    )
    if mrclam:
        problem = not_a_file(folder / BARCODES)
        if problem is not None:
            raise InputError(folder / BARCODES, None, f"{problem}; this MRCLAM dataset needs it")
        if args.robot is None:
            raise InputError(folder, None, "a MRCLAM dataset needs --robot N (1-5)")
        max_range = getattr(args, "max_range", None)
        run, report = load_mrclam(folder, args.robot, max_range=max_range)
        return with_start(run, args), report
    if args.robot is not None:
        raise InputError(folder, None, "--robot is only for MRCLAM datasets (no Barcodes.dat)")
    if not ours and not any((folder / name).exists() for name in ("controls.csv", "frames.csv")):
        raise InputError(
            folder, None, "no run.json (our run format) and no Barcodes.dat (MRCLAM) in this folder"
        )
    # A run logged as camera frames, with no detections.csv yet: detect the tags in its frames.
    if getattr(args, "max_range", None) is not None:
        raise InputError(folder, None, "--max-range is only for MRCLAM datasets (no Barcodes.dat)")
    if has_frames_only(folder):
        # vision.frames_run loads OpenCV (~25 ms): only for a run logged as frames, not every run
        frames_run = importlib.import_module("ekfslam.vision.frames_run")
        run, frames = frames_run.read_frames_run(folder)
        return with_start(run, args), frames
    return with_start(read_run(folder), args), None


def with_start(run: RunLog, args: argparse.Namespace) -> RunLog:
    """The run, starting at ``--start`` when given (`ekfslam.cli.args.add_replay_start_arguments`).

    Whether or not the run has ground truth: the filter starts at the nominal start, eq. (17)
    recovers the true start from the map (``alignment.start_pose``).
    """
    start = getattr(args, "start", None)
    if start is None:
        return run
    return replace(run, meta=replace(run.meta, nominal_start=np.array(start, dtype=np.float64)))


def add_iterations_argument(p: ca.Parser) -> None:
    """``--iterations N``, the iterated update (`FilterConfig.iterations`), for `noise_from_args`;
    with ``--linearization fej`` one line naming it (FEJ keeps each Jacobian where it was first
    evaluated)."""
    p.add_argument(
        "--iterations",
        type=ca.whole(1, 100),
        default=1,
        help="linearisations per update: 1 is the EKF (default), more the iterated EKF, each "
        "further step taken only if it fits the sighting and the prior better (standard or "
        "invariant)",
    )

    def check(args: argparse.Namespace) -> str | None:
        if args.iterations > 1 and args.linearization == "fej":
            return "argument --iterations: only with --linearization standard or invariant"
        return None

    p.add_check(check)


def noise_from_args(
    args: argparse.Namespace, run: RunLog, base: NoiseConfig | None = None
) -> tuple[NoiseConfig, FilterConfig]:
    """The run's default noise (or `base`) and filter choices, with the command line's
    overrides."""
    base = default_noise(run) if base is None else base
    overrides = {
        name: getattr(args, name)
        for name in ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")
        if getattr(args, name) is not None
    }
    noise = replace(base, **overrides)  # validated again, as a new NoiseConfig
    config = replace(
        default_config(run),
        init=args.init,
        gate=None if args.gate == 0 else args.gate,
        linearization=args.linearization,
        iterations=args.iterations,
    )
    if args.reinit_after is not None:
        config = replace(config, reinit_after=args.reinit_after or None)
    return noise, config


def arena_half_size(run: RunLog) -> float | None:
    """The seed's arena walls are drawn when the run's tag map is the seed's (m), else None."""
    tags = run.meta.tag_map or {}
    seed = SEED_ARENA.tag_map()
    same = tags.keys() == seed.keys() and all(
        abs(tags[i][0] - seed[i][0]) < 1e-9 and abs(tags[i][1] - seed[i][1]) < 1e-9 for i in seed
    )
    return SEED_ARENA.half_size if same else None


#: The largest bank ``--hypotheses`` takes (``run``, ``score-mrclam``): every hypothesis is a
#: filter, so the cost grows with it.
MAX_HYPOTHESES = 256


def add_hypotheses_argument(p: argparse.ArgumentParser) -> None:
    """``--hypotheses K``: the size of mht's bank (`AssociationConfig.hypotheses`); None when
    not given, so a command can tell it was asked for without ``--association mht``."""
    p.add_argument(
        "--hypotheses",
        type=ca.whole(1, MAX_HYPOTHESES, why="each costs a filter"),
        default=None,
        metavar="K",
        help="with --association mht: how many hypotheses the bank keeps "
        f"(default {AssociationConfig().hypotheses}; 1 is jcbb)",
    )


def add_passes_argument(p: argparse.ArgumentParser) -> None:
    """``--passes N``: decide the run N times, each pass from the last one's map
    (`ekfslam.pipeline.replay`'s ``passes``); 1 when not given."""
    p.add_argument(
        "--passes",
        type=ca.whole(1, MAX_PASSES, why="each reads the whole run again"),
        default=1,
        metavar="N",
        help="with hidden ids: decide the whole run up to N times, each "
        "pass again from the map the last one ended with (offline: the run is read N times), "
        "and keep the pass whose map fits its sightings best (default 1)",
    )


def add_founding_arguments(p: argparse.ArgumentParser) -> None:
    """``--time-error shared|independent`` and ``--new-rule density|threshold``: how a hidden-id
    replay treats a camera time stamp's error (`AssociationConfig.time_shared`) and what makes a
    sighting new (`AssociationConfig.new_rule`); None when not given (the source's and the
    method's own), so a command can tell they were asked for; `time_shared_of` reads the first."""
    p.add_argument(
        "--time-error",
        choices=("shared", "independent"),
        default=None,
        help="with hidden ids: a camera time stamp's error is one per image, shared by its "
        "sightings (the default where the stamps are off, as on MRCLAM), or independent per "
        "sighting",
    )
    p.add_argument(
        "--new-rule",
        choices=NEW_RULES,
        default=None,
        help="with jcbb or mht: what makes a sighting no landmark takes a new landmark's "
        "(density: no landmark explains it better than a new one, jcbb's default; threshold: "
        "its NIS exceeds 23 against every one, mht's default)",
    )


def time_shared_of(args: argparse.Namespace) -> bool | None:
    """``--time-error`` as `AssociationConfig.time_shared` (None: the source's own)."""
    choice = getattr(args, "time_error", None)
    return None if choice is None else choice == "shared"
