"""Notebook 08 exported to HTML with no browser and no widget frontend still shows its figure.

``jupyter nbconvert --execute --to html`` runs the notebook in a kernel with no frontend: the
ipympl canvas is never drawn, so the panel leaves a static PNG of its figure (and the Table 1
text) after the live widget (`ekfslam.ui.widgets.TuningPanel.static_html`). The export runs on a
copy of the notebook in a temporary folder with throwaway Jupyter folders.
"""

from __future__ import annotations

import base64
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.browser import jupyter_home

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "notebooks" / "08-live-tuning.ipynb"
IMG = re.compile(r'<img[^>]*src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def test_the_exported_notebook_holds_the_panels_figure_as_a_png(tmp_path):
    pytest.importorskip("nbconvert")
    shutil.copy(NOTEBOOK, tmp_path / NOTEBOOK.name)
    env = jupyter_home(tmp_path / "jupyter")
    env["PYTHONPATH"] = str(REPO)
    cmd = [sys.executable, "-m", "jupyter", "nbconvert", "--execute", "--to", "html"]
    cmd += ["--ExecutePreprocessor.timeout=300", NOTEBOOK.name]
    done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    page = (tmp_path / "08-live-tuning.html").read_text(encoding="utf-8")
    assert 'class="ekfslam-static"' in page
    static = page[page.index('class="ekfslam-static"') :]
    images = IMG.findall(static[:2_000_000])
    assert images, "no base64 PNG in the panel's static fallback"
    png = base64.b64decode(images[0])
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", png[16:24])
    assert width >= 600 and height >= 400, (width, height)  # the 9x6 in figure, not an icon
    assert "square-2laps" in static  # the Table 1 row under it
