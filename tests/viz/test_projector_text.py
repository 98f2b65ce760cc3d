"""Figures for a projector: every text of the lab's figures (titles, labels, tick labels,
legends, annotations) is at least 11 pt, and the camera overlay's labels are white on black."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb")) + sorted(
    (ROOT / "solutions").glob("*.ipynb")
)
PROJECTOR_PT = 11.0
#: what the notebooks' second cell sets (08's live panel sets its own sizes)
NOTEBOOK_RC = {"figure.figsize": (9, 6), "font.size": PROJECTOR_PT}


def small_texts(fig: Figure) -> list[str]:
    """'text (size pt)' of every visible, non-empty Text artist below 11 pt."""
    fig.canvas.draw()  # tick labels exist only once drawn
    found = []
    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_fontsize() < PROJECTOR_PT:
            found.append(f"{t.get_text()!r} ({t.get_fontsize():g} pt)")
    return found


def code_of(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")


def test_the_detector_is_a_working_detector() -> None:
    fig = Figure()
    ax = fig.subplots()
    ax.plot([0, 1], label="a")
    ax.legend(fontsize=12)
    ax.annotate("tag 3", (0, 0), fontsize=7)
    assert small_texts(fig) == ["'tag 3' (7 pt)"]


#: the calls whose ``size=`` is no text's: a sensor's measurement size (`SensorModel(size=1)`)
NOT_TEXT = frozenset({"SensorModel", "MotionModel", "RelativeModel"})


def text_sizes(code: str) -> list[float]:
    """The numbers a notebook's code gives ``fontsize=``, ``labelsize=`` or ``size=`` (a
    matplotlib text's alias), except where the call is a model record's (`NOT_TEXT`)."""
    cleaned = "\n".join(
        "" if line.lstrip().startswith(("%", "!")) else line for line in code.splitlines()
    )
    sizes = []
    for node in ast.walk(ast.parse(cleaned)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        for keyword in node.keywords:
            if keyword.arg == "size" and name in NOT_TEXT:
                continue
            if keyword.arg in ("fontsize", "size", "labelsize") and isinstance(
                keyword.value, ast.Constant
            ):
                if isinstance(keyword.value.value, int | float):
                    sizes.append(float(keyword.value.value))
    return sizes


def test_the_size_reader_finds_text_sizes_and_not_a_sensors() -> None:
    code = "ax.legend(fontsize=9)\nm = SensorModel(h=h, size=1)\nax.text(0, 0, 'a', size=12)"
    assert text_sizes(code) == [9.0, 12.0]


def test_no_notebook_asks_for_a_size_below_11_pt_and_each_sets_11_pt() -> None:
    for path in NOTEBOOKS:
        code = code_of(path)
        sizes = text_sizes(code)
        assert all(s >= PROJECTOR_PT for s in sizes), f"{path.name}: text sizes {sizes}"
        if path.name != "08-live-tuning.ipynb":
            assert '"font.size": 11' in code, f"{path.name} does not set font.size to 11"


def test_notebook_06s_animation_frames_keep_11_pt_text_readable_on_screen() -> None:
    """The jshtml frames are pixels shown at their own size: at dpi 60 an 11 pt label was
    9 px high on the page (the rendered notebook), at 80 it is about 12 px, a browser's own."""
    import inspect

    from ekfslam.viz.animation import ReplayFrames

    code = code_of(ROOT / "solutions" / "06-full-slam.ipynb")
    given = re.findall(r"ReplayFrames\((?:[^()]|\([^()]*\))*?\bdpi=(\d+)", code)
    default = inspect.signature(ReplayFrames).parameters["dpi"].default  # the notebook's
    dpi = int(given[0]) if given else default
    assert PROJECTOR_PT * dpi / 72 >= 12.0, f"11 pt at dpi {dpi}"


@pytest.fixture
def projector_rc():
    with matplotlib.rc_context(NOTEBOOK_RC):
        yield


def test_figure2_and_the_map_text_is_11_pt(projector_rc, square, square_result) -> None:
    from ekfslam.analysis.alignment import align
    from ekfslam.viz.plotting import figure2, plot_map

    a = align(square_result.landmarks, square.meta.tag_map)
    assert small_texts(figure2(square, square_result, arena_half_size=0.75, alignment=a)) == []
    fig = Figure()
    plot_map(fig.subplots(), square, square_result, arena_half_size=0.75)
    assert small_texts(fig) == []


def test_the_covariance_matrix_labels_are_11_pt(projector_rc, square_result) -> None:
    from ekfslam.viz.plotting import plot_covariance_matrix

    fig = Figure(figsize=(13, 12))
    ids = sorted(square_result.landmarks)
    n = 3 + 2 * len(ids)
    plot_covariance_matrix(fig.subplots(), np.eye(n), ids, title="t = end")
    assert small_texts(fig) == []


def test_the_camera_overlay_labels_are_white_on_black_inside_the_frame() -> None:
    import cv2

    from ekfslam.vision.detect import LABEL_SCALE, label_box

    image = np.full((480, 640, 3), 128, np.uint8)
    label_box(image, ("tag 1", "1.015 m -18.5 deg"), (600, 180), LABEL_SCALE)
    box = np.argwhere(image[:, :, 0] != 128)
    assert box[:, 1].max() < 640 and box[:, 0].min() >= 0  # pushed left, not cut off
    inside = image[box[:, 0].min() : box[:, 0].max() + 1, box[:, 1].min() : box[:, 1].max() + 1]
    assert set(np.unique(inside[:, :, 0])) >= {0, 255}
    assert (inside[:, :, 0] > 128).mean() < 0.5  # light text on a dark box
    (_, height), _ = cv2.getTextSize("tag 1", cv2.FONT_HERSHEY_SIMPLEX, LABEL_SCALE, 1)
    assert height >= 13  # px on a 640 px frame: ~11 pt on the notebook's 9-inch figure
