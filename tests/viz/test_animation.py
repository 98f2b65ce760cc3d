"""Tests of ekfslam.viz.animation: a replay's frames move as the filter does."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from PIL import Image

from ekfslam import replay
from ekfslam.analysis.laps import lap_times
from ekfslam.errors import EkfSlamError
from ekfslam.viz import animation
from ekfslam.viz.animation import ReplayFrames, replay_animation, save_animation

FRAMES = 16
# an animation counted but not rendered warns when collected, which may be in a later test
pytestmark = pytest.mark.filterwarnings("ignore:Animation was deleted without rendering")


@pytest.fixture(scope="module")
def framed(square):
    return replay(square, keyframes=FRAMES)


@pytest.fixture(scope="module")
def frames(square, framed):
    return ReplayFrames(square, framed, lap_ends=lap_times(square), dpi=40)


def _area(ellipse) -> float:
    return float(np.pi * ellipse.width * ellipse.height / 4.0)


def test_the_animation_has_one_frame_per_keyframe(square, framed) -> None:
    anim = replay_animation(square, framed, dpi=40)
    assert len(list(anim.new_frame_seq())) == len(framed.keyframes) == FRAMES


def test_the_trajectory_grows_to_the_whole_history(frames, framed) -> None:
    lengths = []
    for f in range(len(frames)):
        frames.draw(f)
        lengths.append(len(frames.trajectory.get_xdata()))
    assert lengths[0] <= 1  # the start: nothing driven yet
    assert np.all(np.diff(lengths) >= 0)
    assert lengths[len(lengths) // 2] < lengths[-1] == len(framed.history.t)


def test_each_landmark_ellipse_appears_when_seen_and_ends_smaller(frames, framed) -> None:
    kf = framed.keyframes
    first_area: dict[int, float] = {}
    for f in range(len(frames)):
        frames.draw(f)
        for j, ellipse in enumerate(frames.landmark_ellipses):
            assert ellipse.get_visible() == (j < (kf.dim[f] - 3) // 2)
            if ellipse.get_visible():
                first_area.setdefault(j, _area(ellipse))
    assert len(first_area) == len(kf.landmark_ids) == len(framed.landmarks)
    last = [_area(e) for e in frames.landmark_ellipses]  # the last frame: the final map
    for j, area in first_area.items():
        assert last[j] < area, f"landmark slot {j}: {last[j]:.2e} m² at the end, {area:.2e} first"
    # the final ellipse is the final covariance's 95% one: π χ²(95%) √det Σ_ll
    cov = framed.landmark_covariances[int(kf.landmark_ids[0])]
    assert last[0] == pytest.approx(np.pi * 5.991464547 * np.sqrt(np.linalg.det(cov)), rel=1e-6)


def test_the_correlation_image_fills_in(frames, framed) -> None:
    kf = framed.keyframes
    D = kf.mu.shape[1]
    shown = []
    for f in (0, len(frames) // 2, len(frames) - 1):
        frames.draw(f)
        image = frames.correlation.get_array()
        shown.append(int(np.count_nonzero(~np.ma.getmaskarray(image))))
        assert shown[-1] == kf.dim[f] ** 2
    assert shown[0] == 9 and shown[-1] == D * D
    np.testing.assert_allclose(np.diag(image), 1.0, atol=1e-12)  # every variance > 0 at the end


def test_the_caption_names_time_lap_and_map(frames, framed) -> None:
    frames.draw(len(frames) - 1)
    text = frames.title.get_text()
    assert "lap 2 of 2" in text and f"{len(framed.landmarks)} landmarks" in text


def test_a_replay_without_keyframes_is_refused(square, square_result) -> None:
    with pytest.raises(ValueError, match=r"replay\(run, keyframes=F\)"):
        ReplayFrames(square, square_result)


def test_a_gif_has_every_frame(square, tmp_path) -> None:
    result = replay(square, keyframes=5)
    path = save_animation(ReplayFrames(square, result, dpi=30), tmp_path / "a.gif", fps=5)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == 5
        assert gif.info["duration"] == 200  # ms, 5 frames a second
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif"]  # no partial file left


def test_an_unknown_format_is_refused(frames, tmp_path) -> None:
    with pytest.raises(ValueError, match=r"must end in \.gif, \.mp4"):
        save_animation(frames, tmp_path / "a.avi")


def test_an_mp4_without_ffmpeg_says_how_to_get_it(frames, tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(animation, "ffmpeg_path", lambda: None)
    with pytest.raises(RuntimeError, match="pip install imageio-ffmpeg"):
        save_animation(frames, tmp_path / "a.mp4")
    assert not list(tmp_path.iterdir())


def test_an_mp4_is_written_with_ffmpeg(square, tmp_path) -> None:
    if animation.ffmpeg_path() is None:
        pytest.skip("no ffmpeg: pip install imageio-ffmpeg (the optional extra ekfslam[video])")
    result = replay(square, keyframes=4)
    path = save_animation(ReplayFrames(square, result, dpi=30), tmp_path / "a.mp4", fps=4)
    head = path.read_bytes()[:12]
    assert head[4:8] == b"ftyp" and path.stat().st_size > 1000


def test_landmark_labels_name_the_correlation_blocks(square, framed) -> None:
    labels = [f"tag {i}" for i in framed.keyframes.landmark_ids]
    frames = ReplayFrames(square, framed, landmark_labels=labels, dpi=30)
    shown = [t.get_text() for t in frames.corr_ax.get_xticklabels()]
    assert shown == ["robot", *labels]
    with pytest.raises(ValueError, match="1 labels for 8 landmarks"):
        ReplayFrames(square, framed, landmark_labels=["a"])


def test_times_are_shown_since_the_start(square, framed, frames) -> None:
    # MRCLAM's clock is Unix time: 1.2e9 s on the caption and axis said nothing
    shift = 1.248e9
    h, kf = framed.history, framed.keyframes
    late = dataclasses.replace(
        framed,
        history=dataclasses.replace(h, t=h.t + shift),
        keyframes=dataclasses.replace(kf, t=kf.t + shift),
    )
    later = ReplayFrames(square, late, lap_ends=lap_times(square) + shift, dpi=30)
    f = len(frames) // 2
    frames.draw(f)
    later.draw(f)
    assert later.title.get_text() == frames.title.get_text()
    assert f"t = {kf.t[f] - kf.t[0]:6.1f} s" in later.title.get_text()
    np.testing.assert_allclose(later.sigma_ax.get_xlim(), frames.sigma_ax.get_xlim(), atol=1e-6)
    assert later.sigma_ax.get_xlim()[0] == 0.0


def test_a_failing_ffmpeg_is_one_error_and_leaves_nothing(square, tmp_path, monkeypatch) -> None:
    # an ffmpeg that exits at once: before, its BrokenPipe/CalledProcessError reached the user
    # as a traceback
    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nexit 3\n")
    fake.chmod(0o755)
    monkeypatch.setattr(animation, "ffmpeg_path", lambda: str(fake))
    result = replay(square, keyframes=3)
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(EkfSlamError, match=r"a\.mp4: ffmpeg failed, nothing written"):
        save_animation(ReplayFrames(square, result, dpi=30), out / "a.mp4", fps=3)
    assert not list(out.iterdir())


def test_the_notebooks_animation_is_projector_sized_and_loads_nothing(square, framed) -> None:
    """Regression: 06's animation was drawn at 80 dpi (1120 px wide), and its player's buttons
    were font-awesome icons from a CDN, blank offline."""
    wide = ReplayFrames(square, framed)
    assert wide.figure.get_figwidth() * wide.figure.dpi >= 1920
    page = ReplayFrames(square, framed, dpi=20).html(fps=4)
    assert "<img" in page or "data:image" in page
    assert "font-awesome" not in page and "https://" not in page and "http://" not in page
    assert 'class="fa' not in page
    assert page.count('aria-hidden="true">\u25b6</span>') == 1  # the play button, as a glyph
