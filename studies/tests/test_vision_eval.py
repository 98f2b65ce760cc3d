"""``python -m studies vision-eval``: its table, and a run replayed from its frames against the same
run replayed from the simulator's exact detections (the vision issue's 1.2x target)."""

from __future__ import annotations

from pathlib import Path

import pytest
from studies_cli import studies_main

from ekfslam.analysis.vision_eval import TARGETS
from studies.vision_eval import compare_replays

REPO = Path(__file__).resolve().parents[2]
DATA_RUN = REPO / "data" / "runs" / "square-1lap-frames"


def test_vision_eval_command_prints_the_targets(capsys) -> None:
    assert studies_main(["vision-eval", "--poses", "3", "--seed", "2"]) == 0
    out = capsys.readouterr().out
    assert "3 random poses" in out and "targets:" in out and "range median" in out
    assert "wrong ids passed on: 0" in out


@pytest.mark.slow
def test_the_shipped_frames_run_replays_as_well_as_its_exact_detections() -> None:
    """The issue's target: the map from the frames within 1.2x of the exact detections' error.

    The simulator sees the tags the vision finds (the same camera, the same rule), so the
    frames and the exact detections hold nearly the same sightings.
    """
    c = compare_replays(DATA_RUN)  # about 6 s: detects 281 frames
    assert c.ratio <= TARGETS["replay_ratio"] == 1.2, c
    assert c.vision_ratio <= 1.2, c
    assert c.exact_detections > 200
    assert c.common_detections >= 0.97 * max(c.frames_detections, c.exact_detections), c


def test_frames_rendered_with_another_camera_are_refused(tmp_path: Path) -> None:
    # frames from a camera moved on the robot would not show what the simulator saw: the
    # comparison refuses them before detecting anything
    text = (DATA_RUN / "run.json").read_text()
    moved = '"camera_mounting": {"x": 0.0, "y": 0.0, "yaw": 0.0}'
    assert '"camera_mounting": {"x": 0.06, "y": 0.0, "yaw": 0.0}' in text
    (tmp_path / "run.json").write_text(
        text.replace('"camera_mounting": {"x": 0.06, "y": 0.0, "yaw": 0.0}', moved)
    )
    with pytest.raises(ValueError, match="render them again"):
        compare_replays(tmp_path)
