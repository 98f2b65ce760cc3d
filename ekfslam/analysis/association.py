"""How well a replay with hidden ids associated, against the ids the run knows (issue 16).

The filter named its landmarks 0, 1, 2 ... (`ekfslam.core.filter.associating`); the run's
detections still carry the true ids. `score` maps each estimated landmark to the true id most of
its sightings had (`ekfslam.core.association.confusion`) and returns the replay with its map keyed
by true id through that mapping, so the alignment of eq. (17) and every score downstream compare
the same landmarks as with known ids. An estimated landmark whose true id a more-seen one
already has (a duplicate) is left out of that map, and counted. With ``match="position"`` the map
is keyed instead by matching positions, as for a run whose sightings carry no true ids
(`ekfslam.analysis.alignment_unlabelled`); the decisions are still scored against the ids.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.analysis.alignment_unlabelled import MATCHED_BY_NEAREST, match_by_position
from ekfslam.core.association import AssociationConfig, Confusion, confusion
from ekfslam.core.noise import NoiseConfig, default_noise
from ekfslam.logs.hidden_ids import hidden_id_defaults
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult

Array = NDArray[np.float64]

#: How eq. (17) matched landmarks, said in the output.
MATCHED_THROUGH_MAPPING = "estimated landmarks matched to true ids through the association mapping"
#: `score`'s matchings, and what the output says of each.
MATCHINGS = {"mapping": MATCHED_THROUGH_MAPPING, "position": MATCHED_BY_NEAREST}


def association_config(
    run: RunLog,
    method: str,
    hypotheses: int | None = None,
    time_shared: bool | None = None,
    new_rule: str | None = None,
) -> AssociationConfig:
    """The association a run is replayed with: `method`, and its source's time-stamp uncertainty.

    hypotheses : ``mht``'s bank size (`AssociationConfig.hypotheses`; None: its default).
    time_shared : one time-stamp error per image (True) or per sighting (False); None: the
    source's (`ekfslam.logs.hidden_ids.HiddenIdDefaults.time_shared`).
    new_rule : `AssociationConfig.new_rule` (None: its default).

    A source's time stamps may be off the odometry's (MRCLAM's camera by tenths of a second,
    `ekfslam.logs.mrclam.defaults.MRCLAM_TIME_SIGMA`); every other run's are exact.
    """
    source = hidden_id_defaults(run.meta)
    bank = {} if hypotheses is None else {"hypotheses": hypotheses}
    if time_shared is None:
        time_shared = source is not None and source.time_shared
    if new_rule is not None:
        bank["new_rule"] = new_rule
    return AssociationConfig(
        method=method,
        time_sigma=0.0 if source is None else source.time_sigma,
        time_shared=time_shared,
        **bank,
    )


def association_noise(run: RunLog) -> NoiseConfig:
    """The noise a replay with hidden ids starts from: the run's default, except on MRCLAM.

    Association is a χ² test on the filter's Σ, so it needs a Σ as large as the errors really
    are. MRCLAM's default (`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE`) was tuned for the map
    with the barcodes and leaves Σ too small (pose NEES 12-83 against an ideal 3,
    ``consistency mrclam 7``): the true landmark falls outside its gate, the sighting founds a
    duplicate, and a robot without corrections gets lost. The setting tuned for consistency,
    `ekfslam.logs.mrclam.defaults.MRCLAM_CONSISTENT_NOISE` (NEES 6.1), is used instead.
    """
    source = hidden_id_defaults(run.meta)
    return default_noise(run) if source is None else source.noise


def association_map_noise(run: RunLog) -> NoiseConfig | None:
    """The mapping filter's noise for a replay with hidden ids (`ekfslam.pipeline.replay`'s
    ``map_noise``): on MRCLAM `ekfslam.logs.mrclam.defaults.MRCLAM_MAP_NOISE` (the consistency
    noise decides, a second filter with sigma_x = sigma_y = 0.005 maps); elsewhere None, one
    filter decides and maps (the seed's runs replay with their ideal noise)."""
    source = hidden_id_defaults(run.meta)
    return None if source is None else source.map_noise


def score(
    run: RunLog, result: ReplayResult, match: str = "mapping"
) -> tuple[ReplayResult, Confusion]:
    """The replay with its landmarks keyed by true id, and the confusion of its decisions.

    `result` must come from a replay with hidden ids (``result.association`` set), of `run`.
    match : "mapping" keys the map through the association's mapping; "position" by matching
        the estimated landmarks to the run's tag map by position (`match_by_position`).
    """
    if match not in MATCHINGS:
        raise ValueError(f"match must be one of {', '.join(MATCHINGS)}, got {match!r}")
    log = result.association
    if log is None:
        raise ValueError("this replay used the known ids: there is nothing to score")
    truth = np.asarray(run.detections.tag_id, dtype=int)
    if len(truth) != len(log.estimated):
        raise ValueError(f"{len(log.estimated)} decisions for {len(truth)} detections")
    mapping, found = true_ids(log.estimated, truth, result.landmarks, run.meta.tag_map, match)
    if match == "position" and not mapping:
        return dataclasses.replace(result, landmarks={}, landmark_covariances={}), found
    keep = [e for e in result.landmarks if e in mapping]
    relabelled = dataclasses.replace(
        result,
        landmarks={mapping[e]: result.landmarks[e] for e in keep},
        landmark_covariances={mapping[e]: result.landmark_covariances[e] for e in keep},
    )
    return relabelled, found


def true_ids(
    estimated: ArrayLike, truth: ArrayLike, landmarks: dict, tag_map: dict | None, match: str
) -> tuple[dict[int, int], Confusion]:
    """{estimated id: true id} for a map built with hidden ids, and the confusion of the
    decisions (estimated (N,), truth (N,), `confusion`): through the decisions' mapping
    (duplicates left out), or, with match "position", by matching the map to the tag map
    (`match_by_position`; {} without a tag map or with fewer than 2 landmarks)."""
    found = confusion(estimated, truth)
    if match == "position":
        if not tag_map or len(landmarks) < 2:
            return {}, found
        return match_by_position(landmarks, tag_map).mapping, found
    return {e: t for e, t in found.mapping.items() if e not in found.duplicates}, found


def score_team(team, result, match: str = "mapping") -> tuple[dict[int, Array], Confusion]:
    """The joint map of a team replayed with hidden ids (`ekfslam.team.replay_team`'s
    ``association``), keyed by true id as `score` keys a single replay's, and the confusion of
    every robot's decisions together (each robot's detections in its own order, then the next
    robot's): eq. (17) of the joint map is then `align` of it against the team's tag map."""
    if match not in MATCHINGS:
        raise ValueError(f"match must be one of {', '.join(MATCHINGS)}, got {match!r}")
    estimated, truth = [], []
    for robot in result.robots:
        track = result.tracks[robot]
        if track.estimated is None:
            raise ValueError("this team replay used the known ids: there is nothing to score")
        estimated.append(track.estimated)
        truth.append(np.asarray(team.runs[robot].detections.tag_id, dtype=int))
    mapping, found = true_ids(
        np.concatenate(estimated), np.concatenate(truth), result.landmarks, team.tag_map, match
    )
    return {mapping[e]: p for e, p in result.landmarks.items() if e in mapping}, found


_SIGMAS = ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")


def as_dict(
    result: ReplayResult,
    found: Confusion,
    match: str = "mapping",
    config: AssociationConfig | None = None,
) -> dict:
    """The ``association`` block of ``run --json``: the method, the confusion, the counts; with
    the `config` it replayed with, also its founding rule and time-stamp error."""
    log = result.association
    assert log is not None  # score() refused a replay with known ids
    c = log.counts
    rules = (
        {}
        if config is None
        else {
            "new_rule": config.new_rule,  # what made a sighting new (`AssociationConfig.new_rule`)
            "time_error": {
                "sigma": config.time_sigma,
                "form": "shared" if config.time_shared else "independent",
            },
        }
    )
    block = {
        "method": log.method,
        "correct": found.correct,
        "wrong": found.wrong,
        "missed": found.missed,
        "new": c.confirmed,
        "ambiguous": c.ambiguous,
        "correct_fraction": found.correct_fraction,
        "tentative": c.tentative,
        "tentative_discarded": c.tentative_discarded,
        "duplicates": found.duplicates,
        "jcbb_budget_hits": c.budget_hits,
        "jcbb_nodes": c.nodes,
        "mapping": {str(e): t for e, t in sorted(found.mapping.items())},
        "alignment_matching": MATCHINGS[match],
        "noise": {  # `association_noise`'s choice, with any overrides: what the χ² tests used
            k: getattr(result.noise, k) for k in _SIGMAS
        },
        "map_noise": None  # the mapping filter's, when a second filter mapped the decisions
        if result.map_noise is None
        else {k: getattr(result.map_noise, k) for k in _SIGMAS},
    }
    return block | rules
