"""What the book's pages load, served from the built site: a reader offline sees every page whole.

MathJax is installed at build time from the npm registry (`MATHJAX`, with Debian's ``npm``:
``.ci/install-system.sh`` installs ``nodejs``) into ``docs/_build/.assets/`` once, and copied
into ``_static/mathjax/`` of the site; conf.py's ``mathjax_path`` names it there. Nothing a
page needs comes from a CDN: the theme ships its fonts, the notebooks' widget scripts are not
loaded (``nb_ipywidgets_js = {}``: notebook 08's panel is live in JupyterLab or Voila, and its
page says so), and the animation of 06 is drawn without font-awesome
(``ekfslam.viz.animation.offline_jshtml``). ``tests/integration/test_book_offline.py`` opens
every page with the network cut.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from sphinx.errors import ExtensionError
from sphinx.util import logging

logger = logging.getLogger(__name__)

#: the npm package and version the pages typeset with (MathJax 3: what sphinx.ext.mathjax loads)
MATHJAX = "mathjax@3.2.2"
#: the one combined file the pages load; the others of es5/ are left out of the site
ENTRY = "tex-chtml.js"


def fetch_mathjax(into: Path, npm: str | None = None) -> Path:
    """MathJax's ``es5/`` folder, installed by npm, as `into` (kept once made: the next builds
    reuse it). Raises ExtensionError with what to install when npm is missing or fails."""
    if (into / ENTRY).is_file():
        return into
    npm = npm or shutil.which("npm")
    if npm is None:
        raise ExtensionError(
            f"the book serves MathJax itself and installs it with npm ({MATHJAX}), which is "
            "missing: apt-get install nodejs (or bash .ci/install-system.sh)"
        )
    into.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=into.parent) as tmp:
        command = [npm, "install", "--prefix", tmp, "--no-audit", "--no-fund", "--no-save"]
        command += ["--ignore-scripts", "--loglevel=error", MATHJAX]
        done = subprocess.run(command, capture_output=True, text=True)
        es5 = Path(tmp) / "node_modules" / "mathjax" / "es5"
        if done.returncode or not (es5 / ENTRY).is_file():
            raise ExtensionError(f"npm install {MATHJAX} failed: {done.stderr.strip()[-800:]}")
        for bundle in es5.glob("*.js"):
            if bundle.name not in {ENTRY, "core.js", "loader.js", "startup.js"}:
                bundle.unlink()  # other combined builds the pages never load
        staged = Path(tmp) / "mathjax"
        shutil.move(str(es5), staged)
        staged.rename(into)  # whole or not at all: a failed build leaves no half folder
    logger.info(f"MathJax installed from npm ({MATHJAX}) into {into}")
    return into


def serve_mathjax(app) -> None:
    if app.builder.format != "html":
        return
    static = Path(app.outdir).parent / ".assets" / "static"
    fetch_mathjax(static / "mathjax")
    app.config.html_static_path.append(str(static))


def setup(app):
    app.connect("builder-inited", serve_mathjax)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
