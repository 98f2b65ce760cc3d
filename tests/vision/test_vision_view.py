"""Which tags are fully in view: one rule for the simulator, the renderer and the vision checks.

`ekfslam.core.camera.tags_in_view` is compared with the renderer's own account of where each tag is
in the image (`ArenaRenderer.truth`, written separately, from the scene's surfaces), and the
simulator that uses it with what the vision really finds in the shipped run of camera frames.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from ekfslam.analysis.vision_eval import random_poses
from ekfslam.core.arena import SEED_ARENA
from ekfslam.core.camera import TagSpec, pinhole_camera, tags_in_view
from ekfslam.vision.render import ArenaRenderer

REPO = Path(__file__).resolve().parents[2]
DATA_RUN = REPO / "data" / "runs" / "square-1lap-frames"
TAGS = TagSpec(0.16)


@pytest.mark.parametrize(
    ("mounting", "pitch"), [((0.06, 0.0, 0.0), 0.0), ((0.06, 0.02, 0.2), 0.1), ((0, 0, 0), -0.1)]
)
def test_tags_in_view_is_the_renderers_truth(mounting, pitch) -> None:
    camera = pinhole_camera(pitch=pitch)
    renderer = ArenaRenderer(camera, TAGS, mounting)
    poses = random_poses(150, seed=21)
    truth = [renderer.truth(p) for p in poses]
    limit = math.radians(70.0)
    expected = np.array([t.in_view & (t.incidence <= limit) for t in truth])
    got = tags_in_view(
        camera,
        TAGS,
        mounting,
        poses,
        SEED_ARENA.tag_positions(),
        SEED_ARENA.tag_normals(),
        tag_height=renderer.config.tag_height,
        max_incidence=limit,
    )
    assert got.shape == (150, 8)
    assert 100 < expected.sum() < 600  # both verdicts are well represented
    assert np.array_equal(got, expected)


def test_a_wider_margin_and_a_stricter_angle_see_fewer_tags() -> None:
    camera = pinhole_camera()
    poses = random_poses(200, seed=22)
    args = (
        camera,
        TAGS,
        (0.06, 0.0, 0.0),
        poses,
        SEED_ARENA.tag_positions(),
        SEED_ARENA.tag_normals(),
    )
    base = tags_in_view(*args, max_incidence=math.radians(75.0))
    narrow = tags_in_view(*args, max_incidence=math.radians(45.0))
    inset = tags_in_view(*args, max_incidence=math.radians(75.0), margin_px=40.0)
    assert np.all(narrow <= base) and np.all(inset <= base)
    assert narrow.sum() < 0.9 * base.sum() and inset.sum() < 0.9 * base.sum()
    bigger = tags_in_view(*args[:1], TagSpec(0.3), *args[2:], max_incidence=math.radians(75.0))
    assert np.all(bigger <= base) and bigger.sum() < base.sum()
    with pytest.raises(ValueError, match="mount_height"):
        tags_in_view(dataclasses.replace(camera, mount_height=None), *args[1:])
