"""MRCLAM with its barcodes hidden: each robot's map by ``nn``, ``jcbb``, ``mht`` against ``known``.

`association_robots` replays every robot of a dataset with the barcodes (``known``) and with them
hidden from the filter (with the noise `ekfslam.analysis.association.association_noise` gives:
the setting tuned for consistency, since association trusts Σ), scores the hidden replays'
decisions against the barcodes (`ekfslam.analysis.association.score`) and aligns each map by
eq. (17), the landmarks matched through the association's mapping. `association_table` is the
per-robot table of ``python -m studies score-mrclam DATASET --association nn jcbb``; with
``--linearization`` the replays that associate (and the barcodes' replay under their noise) run
that filter (`ekfslam.core.filter.config.FilterConfig.linearization`), while ``known`` stays the
shipped default, the standard EKF, so every ratio is against the same figure. On MRCLAM the
decisions are then fed as ids to a second filter with the mapping noise
(`ekfslam.analysis.association.association_map_noise`), whose map is scored; ``mapped=False``
(``--map-noise none``) scores the deciding filter's own map.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ekfslam.analysis import association as assoc
from ekfslam.analysis.evaluation import summarize
from ekfslam.analysis.mrclam_tuning import load_robot
from ekfslam.core.association import UNPAIRED
from ekfslam.logs.mrclam.defaults import MRCLAM_CONFIG, MRCLAM_NOISE
from ekfslam.logs.mrclam.load import ROBOTS
from ekfslam.pipeline import decisions_from_known_state, replay
from ekfslam.strategies import HiddenIds


@dataclass(frozen=True)
class AssociationRow:
    """One robot, one method with the ids hidden, against the same robot with them known.

    known_error, aligned_error : m, mean landmark error after eq. (17), with the barcodes (the
    shipped default noise, `MRCLAM_NOISE`) and without (the noise of
    `ekfslam.analysis.association.association_noise`). ratio : aligned_error / known_error.
    known_same_noise, ratio_same_noise : the barcodes' error with the noise the map was made
    with (the mapping noise when `mapped`, else the association noise), and the ratio to it.
    landmarks : mapped landmarks that stand for a true one (duplicates left out).
    correct_fraction, correct, wrong, missed : the decisions
    (`ekfslam.core.association.Confusion`). new, ambiguous, duplicates : landmarks made,
    sightings dropped, estimated landmarks whose true id a more-seen one already had.
    linearization : the filter of the replays with the association noise (`association_robots`).
    mapped : whether the decisions were fed to a second filter with the mapping noise
    (`ekfslam.analysis.association.association_map_noise`), whose map is the one scored.
    passes, chosen_pass, changed : how many passes decided the run (`ekfslam.pipeline.replay`),
    which one the map is, and how many decisions each pass after the first changed.
    wrong_from_known_state : the share of sightings of mapped landmarks the method pairs with
    another landmark when deciding from the state the barcodes give, its errors not fed back
    (`ekfslam.pipeline.decisions_from_known_state`): what the sensor and the map allow. For
    ``mht`` it is JCBB's: from one given state there is no bank to keep.
    """

    robot: int
    method: str
    known_error: float
    aligned_error: float
    ratio: float
    known_same_noise: float
    ratio_same_noise: float
    landmarks: int
    correct_fraction: float | None
    correct: int
    wrong: int
    missed: int
    new: int
    ambiguous: int
    duplicates: int
    wrong_from_known_state: float
    linearization: str = "standard"
    mapped: bool = False
    passes: int = 1
    chosen_pass: int = 1
    changed: tuple[int, ...] = ()


def association_robots(
    dataset_dir: str | Path,
    methods: tuple[str, ...] = ("nn", "jcbb"),
    robots=ROBOTS,
    linearization: str = "standard",
    hypotheses: int | None = None,
    mapped: bool = True,
    time_shared: bool | None = None,
    new_rule: str | None = None,
    passes: int = 1,
) -> list[AssociationRow]:
    """Every robot replayed with ``known`` and with each of `methods`, scored (see the module).

    linearization : the filter of every replay with the association noise; ``known`` (the
    shipped default) is always the standard EKF. hypotheses : ``mht``'s bank size (None: its
    default, `ekfslam.core.association.AssociationConfig.hypotheses`). mapped : map with a
    second filter fed the decisions, with `ekfslam.analysis.association.association_map_noise`
    (the default); False: the deciding filter's own map. time_shared : one time-stamp error
    per image or per sighting (`ekfslam.analysis.association.association_config`; None: the
    source's, one per image). new_rule : what makes a sighting new
    (`ekfslam.core.association.AssociationConfig.new_rule`; None: its default). passes :
    `ekfslam.pipeline.replay`'s (decide the run again from the last pass's map; offline).
    """
    filter_config = dataclasses.replace(MRCLAM_CONFIG, linearization=linearization)
    rows = []
    for robot in robots:
        run = load_robot(str(dataset_dir), robot)
        known = summarize(run, replay(run, MRCLAM_NOISE, MRCLAM_CONFIG))
        base = known.alignment.mean_error if known.alignment else math.nan
        noise = assoc.association_noise(run)
        map_noise = assoc.association_map_noise(run) if mapped else None
        same = summarize(run, replay(run, map_noise or noise, filter_config))  # the map's noise
        same_error = same.alignment.mean_error if same.alignment else math.nan
        known_state: dict[str, float] = {}  # mht decides from one state as jcbb does
        for method in methods:
            config = assoc.association_config(run, method, hypotheses, time_shared, new_rule)
            hidden = replay(
                run,
                noise,
                filter_config,
                association=HiddenIds(config, passes=passes, map_noise=map_noise),
            )
            result, found = assoc.score(run, hidden)
            s = summarize(run, result)
            error = s.alignment.mean_error if s.alignment else math.nan
            counts = result.association.counts
            rule = "nn" if method == "nn" else "jcbb"
            if rule not in known_state:
                known_state[rule] = _wrong_from_known_state(run, noise, filter_config, config)
            wrong_from_known = known_state[rule]
            rows.append(
                AssociationRow(
                    robot=robot,
                    method=method,
                    known_error=base,
                    aligned_error=error,
                    ratio=error / base,
                    known_same_noise=same_error,
                    ratio_same_noise=error / same_error,
                    landmarks=s.landmarks_count,
                    correct_fraction=found.correct_fraction,
                    correct=found.correct,
                    wrong=found.wrong,
                    missed=found.missed,
                    new=counts.confirmed,
                    ambiguous=counts.ambiguous,
                    duplicates=len(found.duplicates),
                    wrong_from_known_state=wrong_from_known,
                    linearization=linearization,
                    mapped=map_noise is not None,
                    passes=passes,
                    chosen_pass=hidden.chosen_pass,
                    changed=tuple(p.changed for p in hidden.passes[1:]),
                )
            )
    return rows


def _wrong_from_known_state(run, noise, filter_config, config) -> float:
    """`AssociationRow.wrong_from_known_state` for one robot and method."""
    chosen = decisions_from_known_state(run, noise, filter_config, association=config)
    truth = np.asarray(run.detections.tag_id, dtype=int)
    t = np.asarray(run.detections.t, dtype=float)
    first = {tag: t[truth == tag].min() for tag in set(truth.tolist())}
    mapped = np.array([first[tag] < time for tag, time in zip(truth.tolist(), t, strict=True)])
    wrong = mapped & (chosen != UNPAIRED) & (chosen != truth)
    return float(wrong.sum() / max(1, mapped.sum()))


def association_table(rows: list[AssociationRow]) -> str:
    """The rows as Markdown: one line per robot and method, then each method's worst ratio."""
    lines = [
        "| robot | method | known (m) | hidden (m) | ratio | known, same noise (m) | ratio "
        "| landmarks | correct | wrong | missed | new | ambiguous | duplicates "
        "| wrong from the barcodes' state |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        share = "none" if r.correct_fraction is None else f"{100 * r.correct_fraction:.1f}%"
        lines.append(
            f"| {r.robot} | {r.method} | {r.known_error:.3f} | {r.aligned_error:.3f} "
            f"| {r.ratio:.2f} | {r.known_same_noise:.3f} | {r.ratio_same_noise:.2f} "
            f"| {r.landmarks} | {share} | {r.wrong} | {r.missed} | {r.new} "
            f"| {r.ambiguous} | {r.duplicates} | {100 * r.wrong_from_known_state:.1f}% |"
        )
    for method in dict.fromkeys(r.method for r in rows):
        for key, what in (("ratio", "known"), ("ratio_same_noise", "known with the same noise")):
            ratios = [getattr(r, key) for r in rows if r.method == method]
            mean = sum(ratios) / len(ratios)
            lines.append(f"{method} / {what}: worst {max(ratios):.2f}, mean {mean:.2f}")
    for lin in dict.fromkeys(r.linearization for r in rows):
        lines.append(f"filter with the association noise: {lin} EKF (known: standard)")
    for r in rows:
        if r.passes > 1:
            changed = ", ".join(str(c) for c in r.changed)
            lines.append(
                f"robot {r.robot} {r.method}: map of pass {r.chosen_pass} of {r.passes} "
                f"(decisions changed per pass: {changed})"
            )
    for mapped in dict.fromkeys(r.mapped for r in rows):
        lines.append(
            "map: a second filter fed the decisions as ids, with the mapping noise "
            "(sigma_x = sigma_y = 0.005)"
            if mapped
            else "map: the deciding filter's own (no mapping filter)"
        )
    return "\n".join(lines)
