"""A replay in motion: the trajectory advancing, the ellipses shrinking, Σ filling in.

One frame per keyframe of the replay (`ekfslam.pipeline.replay(run, keyframes=F)`, the full state
at F moments; `ekfslam.core.filter.history.Keyframes`):

- left, the map: the estimated trajectory up to the frame's time (from `History`, every event),
  the robot and its 95% position ellipse, each landmark seen so far with its 95% ellipse
  (eqs. 12-16 in motion: an ellipse appears large when a tag is first seen and shrinks at each
  re-sighting, most visibly on the second lap, the seed's "driving multiple times");
- right, the correlation matrix of Σ, Σ_ab / √(Σ_aa Σ_bb), growing by two rows and columns per
  new landmark (eq. 12's cross-covariance fills them at once);
- below, the robot's and the map's uncertainty over time, drawn up to the frame's time.

`ReplayFrames` builds the figure and draws any frame (tests read its artists); `animation()` wraps
it in a matplotlib `FuncAnimation` for ``to_jshtml()`` in a notebook, and `save_animation` writes
a GIF (Pillow) or an MP4 (ffmpeg).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib as mpl
import numpy as np
from matplotlib import animation as mpl_animation
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse
from numpy.typing import NDArray

from ekfslam.errors import EkfSlamError
from ekfslam.files import atomic_write
from ekfslam.logs.runlog import RunLog
from ekfslam.viz.plotting import draw_arena, draw_true_landmarks, ellipse_parameters
from ekfslam.viz.style import ESTIMATE, FONT, PROJECTOR_DPI, UNCERTAINTY

if TYPE_CHECKING:
    from ekfslam.pipeline import ReplayResult

#: What `save_animation` writes: GIF through Pillow (always there), MP4 through ffmpeg.
ANIMATION_FORMATS: tuple[str, ...] = (".gif", ".mp4")


class ReplayFrames:
    """The animation's figure and artists; `draw(f)` sets them to keyframe f.

    Parameters
    ----------
    run : the replayed run (its true tags are drawn when it has a tag map).
    result : a replay with keyframes (``replay(run, keyframes=F)``).
    arena_half_size : m, draws the walls when given.
    lap_ends : s, times at which laps end (`ekfslam.analysis.laps.lap_times`): the title says
        which lap a frame is in.
    confidence : of the ellipses (0.95 by default, as in the seed's Figure 2).
    landmark_labels : one per landmark slot, for the correlation matrix; the slots' ids by
        default (with hidden ids those are the filter's own names: give the true ids instead).
    """

    def __init__(
        self,
        run: RunLog,
        result: ReplayResult,
        *,
        arena_half_size: float | None = None,
        lap_ends: Sequence[float] = (),
        confidence: float = 0.95,
        landmark_labels: Sequence[str] | None = None,
        figsize: tuple[float, float] = (14.0, 8.5),
        dpi: int = PROJECTOR_DPI,
    ) -> None:
        kf = result.keyframes
        if kf is None or len(kf) == 0:
            raise ValueError("the replay has no keyframes: replay(run, keyframes=F) records them")
        self.keyframes, self.history = kf, result.history
        self.confidence, self.lap_ends = confidence, np.sort(np.asarray(lap_ends, dtype=float))
        labels = [str(i) for i in kf.landmark_ids] if landmark_labels is None else landmark_labels
        if len(labels) != len(kf.landmark_ids):
            raise ValueError(f"{len(labels)} labels for {len(kf.landmark_ids)} landmarks")
        self.landmark_labels = list(labels)
        self.figure = fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
        _OffscreenCanvas(fig)  # no pyplot, no window: safe in tests, scripts and notebooks
        axes = fig.subplot_mosaic(
            [["map", "corr"], ["sigma", "sigma"]], height_ratios=[3.2, 1.0], width_ratios=[1, 1]
        )
        self.map_ax, self.corr_ax, self.sigma_ax = axes["map"], axes["corr"], axes["sigma"]
        self._build_map(run, result, arena_half_size)
        self._build_correlation()
        self._build_sigma()
        self.title = self.map_ax.set_title("", fontsize=FONT + 1)
        # lay the figure out once, on the fullest frame, then keep it: the constrained layout
        # would be solved again for every frame (half of a frame's drawing time)
        self.draw(len(self) - 1)
        fig.canvas.draw()
        # None, not "none": a placeholder engine makes every savefig draw twice (a dry run)
        fig.set_layout_engine(None)

    def __len__(self) -> int:
        return len(self.keyframes)

    # ----------------------------------------------------------------------------- building
    def _build_map(self, run: RunLog, result: ReplayResult, half_size: float | None) -> None:
        ax, kf, h = self.map_ax, self.keyframes, self.history
        if half_size is not None:
            draw_arena(ax, half_size)
        if run.meta.tag_map:
            draw_true_landmarks(ax, run.meta.tag_map)
        (self.trajectory,) = ax.plot([], [], "-", color=ESTIMATE, lw=1.5, label="estimated path")
        (self.heading,) = ax.plot([], [], "-", color=ESTIMATE, lw=3)
        (self.robot,) = ax.plot([], [], "o", color=ESTIMATE, ms=7, label="robot")
        self.robot_ellipse = ax.add_patch(
            Ellipse((0.0, 0.0), 0.0, 0.0, fill=False, color=ESTIMATE, lw=1.5)
        )
        (self.landmarks,) = ax.plot(
            [], [], "o", mfc="none", mec=ESTIMATE, ms=9, mew=1.5, label="estimated landmarks"
        )
        self.landmark_ellipses: list[Ellipse] = []
        for _ in kf.landmark_ids:
            e = ax.add_patch(Ellipse((0.0, 0.0), 0.0, 0.0, fill=False, color=UNCERTAINTY, lw=1.5))
            e.set_visible(False)
            self.landmark_ellipses.append(e)
        ax.plot([], [], "-", color=UNCERTAINTY, label=f"{self.confidence:.0%} ellipses")
        # the window: the whole run's path and map, so that nothing moves but the estimate
        points = [h.pose[:, :2]] if len(h.t) else []
        points += [kf.mu[-1, 3 : kf.dim[-1]].reshape(-1, 2)]
        if run.meta.tag_map:
            points.append(np.array(list(run.meta.tag_map.values()), dtype=float))
        if half_size is not None:
            points.append(np.array([[-half_size, -half_size], [half_size, half_size]]))
        xy = np.vstack(points)
        lo, hi = np.nanmin(xy, axis=0), np.nanmax(xy, axis=0)
        pad = 0.08 * float(np.max(hi - lo)) + 0.1
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)", fontsize=FONT)
        ax.set_ylabel("y (m)", fontsize=FONT)
        ax.tick_params(labelsize=FONT)
        ax.grid(True, alpha=0.3)
        # below the map: inside, the legend hid a landmark
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=FONT - 1)

    def _build_correlation(self) -> None:
        ax, kf = self.corr_ax, self.keyframes
        D = kf.mu.shape[1]
        cmap = mpl.colormaps["RdBu_r"].with_extremes(bad="0.92")  # grey: not in the state yet
        self.correlation = ax.imshow(
            np.ma.masked_all((D, D)), cmap=cmap, vmin=-1.0, vmax=1.0, interpolation="nearest"
        )
        # one label per block (the robot, then each landmark's two rows): 11 pt fits
        ticks = [1.0] + [3.5 + 2 * j for j in range(len(kf.landmark_ids))]
        names = ["robot", *self.landmark_labels]
        ax.set_xticks(ticks, names, rotation=90, fontsize=FONT)
        ax.set_yticks(ticks, names, fontsize=FONT)
        for edge in [2.5 + 2 * j for j in range(len(kf.landmark_ids))]:
            ax.axhline(edge, color="white", lw=0.5)
            ax.axvline(edge, color="white", lw=0.5)
        ax.set_title(
            "correlations in Σ (eq. 1 order: robot, then tags as first seen)", fontsize=FONT
        )
        bar = self.figure.colorbar(self.correlation, ax=ax, shrink=0.8)
        bar.ax.tick_params(labelsize=FONT)

    def _build_sigma(self) -> None:
        ax, kf, h = self.sigma_ax, self.keyframes, self.history
        self.landmark_sigma = np.array(
            [_mean_landmark_sigma(kf.Sigma[f], kf.dim[f]) for f in range(len(kf))]
        )
        robot = np.sqrt(h.pose_cov[:, 0, 0] + h.pose_cov[:, 1, 1]) if len(h.t) else np.zeros(0)
        (self.robot_sigma_line,) = ax.plot([], [], "-", color=ESTIMATE, label="robot √(Σxx + Σyy)")
        (self.map_sigma_line,) = ax.plot(
            [], [], "o-", color=UNCERTAINTY, ms=3, label="landmarks, mean √trace Σ_ll"
        )
        self._robot_sigma = 100.0 * robot
        t0 = self.t0 = float(kf.t[0])  # times since the start: MRCLAM's clock is Unix time
        t_end = max(float(kf.t[-1]), float(h.t[-1]) if len(h.t) else t0) - t0
        ax.set_xlim(0.0, t_end if t_end > 0 else 1.0)
        top = np.nanmax(np.concatenate([self._robot_sigma, 100.0 * self.landmark_sigma, [1.0]]))
        ax.set_ylim(0.0, 1.1 * top)
        for t in self.lap_ends:
            ax.axvline(t - t0, color="k", lw=1.0)
        ax.set_xlabel(
            "time since the start (s)"
            + ("  (black lines: end of each lap)" if len(self.lap_ends) else ""),
            fontsize=FONT,
        )
        ax.set_ylabel("σ (cm)", fontsize=FONT)
        ax.tick_params(labelsize=FONT)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=FONT - 1)

    # ------------------------------------------------------------------------------ drawing
    def draw(self, f: int) -> list:
        """Set every moving artist to keyframe f (0 <= f < len(self)); returns them."""
        kf, h = self.keyframes, self.history
        t, d = float(kf.t[f]), int(kf.dim[f])
        mu, S = kf.mu[f, :d], kf.Sigma[f, :d, :d]
        e = int(np.searchsorted(h.t, t, side="right"))  # events up to the frame's time
        self.trajectory.set_data(h.pose[:e, 0], h.pose[:e, 1])
        x, y, theta = mu[:3]
        self.robot.set_data([x], [y])
        arm = 0.04 * float(np.diff(self.map_ax.get_xlim())[0])
        self.heading.set_data([x, x + arm * math.cos(theta)], [y, y + arm * math.sin(theta)])
        _set_ellipse(self.robot_ellipse, mu[:2], S[:2, :2], self.confidence)
        n = (d - 3) // 2
        m = mu[3:d].reshape(-1, 2)
        self.landmarks.set_data(m[:, 0], m[:, 1])
        for j, ellipse in enumerate(self.landmark_ellipses):
            seen = j < n
            ellipse.set_visible(seen)
            if seen:
                l = 3 + 2 * j
                _set_ellipse(ellipse, m[j], S[l : l + 2, l : l + 2], self.confidence)
        self.correlation.set_data(_correlation_image(kf.Sigma[f], d))
        self.robot_sigma_line.set_data(h.t[:e] - self.t0, self._robot_sigma[:e])
        self.map_sigma_line.set_data(kf.t[: f + 1] - self.t0, 100.0 * self.landmark_sigma[: f + 1])
        lap = int(np.searchsorted(self.lap_ends, t, side="left")) + 1
        laps = (
            f"lap {min(lap, len(self.lap_ends))} of {len(self.lap_ends)} · "
            if len(self.lap_ends)
            else ""
        )
        self.title.set_text(
            f"t = {t - self.t0:6.1f} s · {laps}{n} landmarks · {kf.detections[f]} detections used"
        )
        return [
            self.trajectory,
            self.heading,
            self.robot,
            self.robot_ellipse,
            self.landmarks,
            *self.landmark_ellipses,
            self.correlation,
            self.robot_sigma_line,
            self.map_sigma_line,
            self.title,
        ]

    def animation(self, fps: float = 10.0) -> mpl_animation.FuncAnimation:
        """A `FuncAnimation` of every keyframe, `fps` frames a second (for ``to_jshtml()``)."""
        return mpl_animation.FuncAnimation(
            self.figure,
            self.draw,
            frames=len(self),
            interval=1000.0 / fps,
            blit=False,
            repeat=True,
            cache_frame_data=False,
        )

    def html(self, fps: float = 10.0, default_mode: str = "loop") -> str:
        """The animation as a page fragment with its player (`offline_jshtml`): for a notebook's
        ``HTML(...)``, and the book's page, which shows it with the network cut."""
        return offline_jshtml(self.animation(fps), default_mode=default_mode)


#: matplotlib's player draws its buttons with font-awesome icons from a CDN: offline they are
#: blank. The same buttons as plain characters, which every font has.
_PLAYER_ICONS = {
    "fa fa-minus": "\u2212",
    "fa fa-fast-backward": "\u21e4",
    "fa fa-step-backward": "\u2039",
    "fa fa-play fa-flip-horizontal": "\u25c0",
    "fa fa-pause": "\u275a\u275a",
    "fa fa-play": "\u25b6",
    "fa fa-step-forward": "\u203a",
    "fa fa-fast-forward": "\u21e5",
    "fa fa-plus": "+",
}
_STYLESHEET = re.compile(r"<link[^>]*font-awesome[^>]*>\s*", re.I)


def offline_jshtml(animation: mpl_animation.Animation, **kwargs) -> str:
    """`animation.to_jshtml(**kwargs)` that loads nothing from the network: the player's
    font-awesome stylesheet left out, its icons written as characters."""
    text = _STYLESHEET.sub("", animation.to_jshtml(**kwargs))
    for icon, glyph in _PLAYER_ICONS.items():
        text = text.replace(f'<i class="{icon}"></i>', f'<span aria-hidden="true">{glyph}</span>')
    return text


def replay_animation(
    run: RunLog, result: ReplayResult, *, fps: float = 10.0, **kwargs
) -> mpl_animation.FuncAnimation:
    """`ReplayFrames(run, result, **kwargs).animation(fps)`: one frame per keyframe."""
    return ReplayFrames(run, result, **kwargs).animation(fps)


def ffmpeg_path() -> str | None:
    """An ffmpeg for MP4: on PATH, else the one the imageio-ffmpeg wheel ships; or None."""
    found = shutil.which("ffmpeg")
    if found:
        return found
    try:
        import imageio_ffmpeg  # lazy: optional (pip install imageio-ffmpeg), only for MP4
    except ImportError:
        return None
    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError:  # the wheel without its binary (an unsupported platform)
        return None


#: What to say when there is no ffmpeg for an MP4.
NO_FFMPEG = (
    "writing .mp4 needs ffmpeg: pip install imageio-ffmpeg (or install ffmpeg), or write a .gif"
)


def save_animation(frames: ReplayFrames, path: str | os.PathLike, fps: float = 10.0) -> Path:
    """Write every frame to `path` (.gif through Pillow, .mp4 through ffmpeg), atomically."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in ANIMATION_FORMATS:
        raise ValueError(f"{path}: an animation must end in {', '.join(ANIMATION_FORMATS)}")
    if suffix == ".gif":
        writer: mpl_animation.AbstractMovieWriter = mpl_animation.PillowWriter(fps=fps)
    else:
        exe = ffmpeg_path()
        if exe is None:
            raise RuntimeError(NO_FFMPEG)
        mpl.rcParams["animation.ffmpeg_path"] = exe
        # yuv420p: the pixel format every player reads; it needs even sizes, hence the scale
        writer = mpl_animation.FFMpegWriter(
            fps=fps,
            codec="libx264",
            extra_args=["-pix_fmt", "yuv420p", "-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2"],
        )

    def write(tmp: Path) -> None:
        # the writer's own loop, not FuncAnimation.save: that draws each frame once more
        with writer.saving(frames.figure, str(tmp), dpi=frames.figure.dpi):
            for f in range(len(frames)):
                frames.draw(f)
                writer.grab_frame()

    try:
        return atomic_write(path, write)
    except (OSError, subprocess.CalledProcessError) as e:  # ffmpeg died, or the disk is full
        what = "ffmpeg failed" if suffix == ".mp4" else "writing failed"
        raise EkfSlamError(f"{path}: {what}, nothing written: {str(e).splitlines()[0]}") from e


class _OffscreenCanvas(FigureCanvasAgg):
    """An Agg canvas that draws only when a frame is saved.

    `FuncAnimation.save` and ``to_jshtml`` ask for a screen redraw after each frame
    (``draw_idle``) and then draw the frame again to save it; off screen the first draw is
    wasted, half of the animation's time.
    """

    def draw_idle(self, *args, **kwargs) -> None:
        pass


def _set_ellipse(e: Ellipse, mean: NDArray, cov: NDArray, confidence: float) -> None:
    width, height, angle = ellipse_parameters(cov, confidence)
    e.set_center((float(mean[0]), float(mean[1])))
    e.set_width(width)
    e.set_height(height)
    e.set_angle(angle)


def _correlation_image(Sigma: NDArray, d: int) -> np.ma.MaskedArray:
    """Σ_ab / √(Σ_aa Σ_bb) of the first d entries, masked beyond; a zero variance gives 0."""
    D = len(Sigma)
    image = np.ma.masked_all((D, D))
    S = Sigma[:d, :d]
    sd = np.sqrt(np.clip(np.diag(S), 0.0, None))
    scale = np.outer(sd, sd)
    image[:d, :d] = np.divide(S, scale, out=np.zeros_like(S), where=scale > 0)
    return image


def _mean_landmark_sigma(Sigma: NDArray, d: int) -> float:
    """Mean over the landmarks of √trace Σ_ll (m); NaN before the first landmark."""
    n = (d - 3) // 2
    if n == 0:
        return math.nan
    diag = np.diag(Sigma)[3:d].reshape(n, 2)
    return float(np.mean(np.sqrt(np.clip(diag.sum(axis=1), 0.0, None))))
