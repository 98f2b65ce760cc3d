"""The arena renderer: deterministic frames, tags drawn where the pinhole model puts them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.arena import SEED_ARENA
from ekfslam.core.camera import Camera, TagSpec, optical_to_robot, pinhole_camera
from ekfslam.vision.corners import undistort
from ekfslam.vision.render import ArenaRenderer, RenderConfig
from ekfslam.vision.scene import CLUTTER_TAG_ID, INK, PAPER, tag_image

TAGS = TagSpec(0.16)
#: No blur, no noise, no vignetting: the radiance is the geometry alone.
CLEAN = RenderConfig(
    blur_sigma=0, vignetting=0, exposure_jitter=0, read_noise=0, shot_noise=0, clutter=False
)
_PAPER, _INK = PAPER, INK


@pytest.fixture(scope="module")
def renderer() -> ArenaRenderer:
    return ArenaRenderer(pinhole_camera(), TAGS)


def _dark_moments(image: np.ndarray, corners: np.ndarray) -> tuple[float, np.ndarray]:
    """Area (px²) and centroid (2,) of the ink inside a window around the tag's corners."""
    x0, y0 = np.floor(corners.min(0)).astype(int) - 4
    x1, y1 = np.ceil(corners.max(0)).astype(int) + 5
    patch = image[y0:y1, x0:x1].astype(float)
    shade = patch.max() / _PAPER  # the wall's light falls on the paper too
    ink = np.clip((_PAPER - patch / shade) / (_PAPER - _INK), 0, None)
    ys, xs = np.mgrid[y0:y1, x0:x1]
    area = ink.sum()
    return area, np.array([(ink * xs).sum(), (ink * ys).sum()]) / area


def _area(c: np.ndarray) -> float:
    """Area of a quadrilateral (4, 2) from its diagonals."""
    (ax, ay), (bx, by) = c[2] - c[0], c[3] - c[1]
    return 0.5 * abs(ax * by - ay * bx)


def _black_modules(tag_id: int) -> tuple[float, np.ndarray]:
    """Fraction of the 8x8-module square that is black, and the black centroid in (0..1)²."""
    bits = 1.0 - tag_image(tag_id, 1).astype(float) / 255.0  # 8 x 8, 1 = black
    ys, xs = np.mgrid[0:8, 0:8] + 0.5
    return bits.mean(), np.array([(bits * xs).sum(), (bits * ys).sum()]) / bits.sum() / 8.0


@pytest.mark.parametrize("distance", [0.25, 0.45, 0.8, 1.3])
def test_a_facing_tag_has_the_printed_size_and_place(distance: float) -> None:
    # Tag 1 on the wall x = 0.75 (facing -x), seen head-on from `distance` m, camera level with
    # it (so the image of the tag is an exact scaled copy): the tag's ink must cover the
    # projected square's area times its black fraction, with its centroid where the black
    # modules' centroid projects. A tag drawn 1 % too small, or half a pixel off, fails.
    camera = pinhole_camera(distortion=(0, 0, 0, 0, 0), mount_height=0.15)
    r = ArenaRenderer(camera, TAGS, config=CLEAN)
    tag = SEED_ARENA.tags[1]
    pose = np.array([tag.position[0] - distance, tag.position[1] + 0.013, 0.0])
    corners = r.truth(pose).corners[1]
    area, centroid = _dark_moments(r.radiance(pose), corners)
    fraction, (cu, cv) = _black_modules(1)
    square = _area(corners)
    assert area == pytest.approx(fraction * square, rel=4e-3)
    # head-on, the square maps almost affinely: interpolate the black centroid in its corners
    top = corners[0] + cu * (corners[1] - corners[0])
    bottom = corners[3] + cu * (corners[2] - corners[3])
    expected = top + cv * (bottom - top)
    # up to 0.07 px: edges parallel to the pixel grid keep the 2x supersampling's steps
    assert np.abs(centroid - expected).max() < 0.1


def test_lens_distortion_moves_the_tag_where_the_camera_model_says() -> None:
    camera = pinhole_camera(distortion=(-0.25, 0.08, 0.001, -0.001, 0.0), mount_height=0.15)
    r = ArenaRenderer(camera, TAGS, config=CLEAN)
    tag = SEED_ARENA.tags[1]
    pose = np.array([tag.position[0] - 0.5, tag.position[1] - 0.17, 0.0])  # tag near the edge
    corners = r.truth(pose).corners[1]
    assert corners[:, 0].min() < 150  # far from the optical axis, where distortion is large
    area, centroid = _dark_moments(r.radiance(pose), corners)
    fraction, _ = _black_modules(1)
    # the pinhole corners (no distortion) would put the tag elsewhere by several pixels
    plain = ArenaRenderer(pinhole_camera(distortion=(0,) * 5, mount_height=0.15), TAGS).truth(pose)
    assert np.abs(plain.corners[1] - corners).max() > 5.0
    inside = (centroid >= corners.min(0)) & (centroid <= corners.max(0))
    assert inside.all()
    square = _area(corners)
    assert area == pytest.approx(fraction * square, rel=0.02)


def test_undistort_inverts_the_projection() -> None:
    camera = pinhole_camera(distortion=(-0.2, 0.05, 0.002, 0.001, 0.01))
    rng = np.random.default_rng(3)
    ideal = rng.uniform([-20, -20], [660, 500], (50, 2))
    normal = (ideal - [camera.cx, camera.cy]) / [camera.fx, camera.fy]
    recorded = camera.project(np.column_stack([normal, np.ones(50)]))
    assert np.abs(undistort(recorded, camera) - ideal).max() < 1e-6


def test_the_same_seed_and_frame_give_the_same_bytes(renderer: ArenaRenderer) -> None:
    pose = (-0.3, -0.2, 0.4)
    a = renderer.render(pose, frame=5)
    assert a.dtype == np.uint8 and a.shape == (480, 640)
    assert np.array_equal(a, renderer.render(pose, frame=5))
    assert np.array_equal(a, ArenaRenderer(pinhole_camera(), TAGS).render(pose, frame=5))
    b = renderer.render(pose, frame=6)  # other noise, same scene
    assert not np.array_equal(a, b)
    assert np.abs(a.astype(float) - b).mean() < 6.0
    other = ArenaRenderer(pinhole_camera(), TAGS, config=RenderConfig(seed=1)).render(pose, 5)
    assert not np.array_equal(a, other)


def test_sensor_noise_exposure_and_blur_are_what_the_config_says(renderer) -> None:
    radiance = renderer.radiance((0.0, 0.0, 0.3))

    def expose(**settings) -> np.ndarray:
        return renderer.expose(radiance, 0, RenderConfig(**(_still() | settings))).astype(float)

    a, b = expose(), expose(read_noise=3.0)
    mid = (a > 20) & (a < 235)  # unclipped pixels
    assert np.std((b - a)[mid]) == pytest.approx(3.0, rel=0.05)
    shot = expose(shot_noise=0.5) - a  # variance 0.5 DN per DN of signal
    dark, light = mid & (a < 80), mid & (a > 150)
    assert np.var(shot[light]) / np.mean(a[light]) == pytest.approx(0.5, rel=0.1)
    assert np.var(shot[dark]) < np.var(shot[light])
    bright, dim = expose(exposure=1.3), a
    ok = (dim > 10) & (dim < 180)
    assert np.median(bright[ok] / dim[ok]) == pytest.approx(1.3, rel=0.02)

    def edge_strength(image: np.ndarray) -> float:  # the steepest step: a tag's edge
        return float(np.abs(np.diff(image, axis=1)).max())

    assert edge_strength(expose(blur_sigma=2.0)) < 0.5 * edge_strength(a)
    # auto-exposure wobble: each frame draws its own gain
    g0 = renderer.expose(radiance, 0, RenderConfig(**(_still() | {"exposure_jitter": 0.1})))
    g1 = renderer.expose(radiance, 1, RenderConfig(**(_still() | {"exposure_jitter": 0.1})))
    assert abs(np.median(g0[ok].astype(float) / g1[ok]) - 1.0) > 0.005


def _still() -> dict:
    return {"read_noise": 0.0, "shot_noise": 0.0, "exposure_jitter": 0.0, "blur_sigma": 0.0}


def test_truth_lists_the_tags_in_view_with_range_and_bearing(renderer: ArenaRenderer) -> None:
    pose = np.array([0.0, 0.0, 0.0])  # at the centre facing +x: tags 0 and 1 at ±26.6 degrees
    truth = renderer.truth(pose)
    assert truth.in_view.tolist() == [True, True] + [False] * 6
    assert truth.range[:2] == pytest.approx([math.hypot(0.75, 0.375)] * 2)
    assert truth.bearing[:2] == pytest.approx([math.atan2(0.375, 0.75), -math.atan2(0.375, 0.75)])
    assert truth.incidence[:2] == pytest.approx([math.atan2(0.375, 0.75)] * 2, abs=0.15)
    # the tag at +bearing (left) appears left of the image centre, its square upright
    assert truth.corners[0, :, 0].mean() < 319.5 < truth.corners[1, :, 0].mean()
    c = truth.corners[0]
    assert c[0, 1] < c[3, 1] and c[0, 0] < c[1, 0]  # top-left above bottom-left, left of top-right
    away = renderer.truth(np.array([0.0, 0.0, math.pi]))  # facing -x: tags 5 and 6
    assert np.flatnonzero(away.in_view).tolist() == [5, 6]


def test_a_tag_cut_by_the_image_border_is_not_in_view(renderer: ArenaRenderer) -> None:
    # turn until tag 1 sits at the right edge of the image
    for heading in np.linspace(0.0, 0.9, 46):
        truth = renderer.truth(np.array([0.0, -0.375, heading]))
        if not truth.in_view[1]:
            break
    assert 0.3 < heading < 0.7
    assert np.isfinite(truth.corners[1]).all()  # still in front of the camera, partly in frame


def test_the_clutter_tag_is_in_the_room_and_not_in_the_map(renderer: ArenaRenderer) -> None:
    assert CLUTTER_TAG_ID not in SEED_ARENA.tag_ids
    clean = ArenaRenderer(pinhole_camera(), TAGS, config=RenderConfig(clutter=False))
    pose = (0.3, -0.5, 2.0)  # this view shows the room wall that holds it (looked at)
    assert not np.array_equal(renderer.render(pose), clean.render(pose))


def test_camera_pose_applies_the_mounting() -> None:
    camera = pinhole_camera(pitch=0.1)
    r = ArenaRenderer(camera, TAGS, mounting=(0.06, 0.02, 0.3))
    centre, R = r.camera_pose((1.0, 2.0, math.pi / 2))
    assert centre == pytest.approx([1.0 - 0.02, 2.0 + 0.06, 0.12])
    # the optical axis, mapped back through optical_to_robot, is the camera's heading and pitch
    axis = optical_to_robot([[0.0, 0.0, 1.0]], (0.0, 0.0, 0.3), 0.1)[0]
    assert axis == pytest.approx(
        [math.cos(0.3) * math.cos(0.1), math.sin(0.3) * math.cos(0.1), -math.sin(0.1)]
    )
    world_axis = R.T @ [0.0, 0.0, 1.0]
    heading = math.pi / 2 + 0.3
    assert world_axis == pytest.approx(
        [math.cos(heading) * math.cos(0.1), math.sin(heading) * math.cos(0.1), -math.sin(0.1)]
    )


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="mount_height"):
        ArenaRenderer(Camera(640, 480, 500, 500, 319.5, 239.5), TAGS)
    with pytest.raises(ValueError, match="supersample"):
        RenderConfig(supersample=0)
    with pytest.raises(ValueError, match="blur_sigma"):
        RenderConfig(blur_sigma=-1)
    with pytest.raises(ValueError, match="distortion"):
        Camera(640, 480, 500, 500, 319.5, 239.5, distortion=(0.1, 0.2, 0.3))
