"""The notebooks in the book: one source (``notebooks/``), and a clear word when data is missing.

- ``docs/notebooks`` is a symbolic link to ``notebooks/``. Sphinx resolves a link's path through
  it, so a notebook's link to another (``[06](06-full-slam.ipynb)``) pointed outside the source
  folder, where no document is: `links_between_notebooks` maps it back.
- A notebook that reads MRCLAM data (a call of ``mrclam_dataset(N)``, the notebooks' one clean
  stop without it) cannot run on a machine without that data. `unexecuted` finds which; conf.py
  leaves them out of execution, `mark_unexecuted` puts a warning under their title, and
  `say_what_is_missing` says so at the start of the build, in red; in CI (``CI=true``) it stops
  the build instead.

Config values: ``ekfslam_notebooks`` (the notebooks' folder) and ``ekfslam_unexecuted``
({docname: the datasets missing}).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterable
from pathlib import Path

from sphinx import addnodes
from sphinx.errors import ExtensionError
from sphinx.util import logging

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset

logger = logging.getLogger(__name__)
CALL = re.compile(r"\bmrclam_dataset\((\d*)\)")


def in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def mrclam_needs(folder: Path) -> dict[str, tuple[int, ...]]:
    """{docname: the MRCLAM datasets it reads} of the numbered notebooks in `folder`."""
    needs = {}
    for path in sorted(folder.glob("[0-9][0-9]-*.ipynb")):
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        numbers = {int(n or 7) for n in CALL.findall(code)}  # mrclam_dataset()'s default: 7
        if numbers:
            needs[f"notebooks/{path.stem}"] = tuple(sorted(numbers))
    return needs


def _here(n: int) -> bool:
    try:
        find_dataset(n)
    except InputError:
        return False
    return True


def unexecuted(folder: Path, here: Callable[[int], bool] = _here) -> dict[str, tuple[int, ...]]:
    """{docname: the datasets it needs that are not on this machine} (`here` says which are)."""
    found = {}
    for doc, numbers in mrclam_needs(folder).items():
        missing = tuple(n for n in numbers if not here(n))
        if missing:
            found[doc] = missing
    return found


def _datasets(numbers: Iterable[int]) -> str:
    return ", ".join(f"MRCLAM Dataset {n}" for n in numbers)


def _fetch(numbers: Iterable[int]) -> str:
    return " and ".join(f"`python -m ekfslam fetch mrclam {n}`" for n in numbers)


def marked(notebook_json: str, numbers: tuple[int, ...]) -> str:
    """The notebook with a warning cell under its title: it was built without `numbers`."""
    nb = json.loads(notebook_json)
    note = (
        "```{warning}\nThis page was built on a machine without "
        f"{_datasets(numbers)}, so its code was not run and it shows no outputs. "
        f"{_fetch(numbers)} fetches the data (or set `EKFSLAM_SHARED_DATA`); then build the "
        "book again.\n```"
    )
    nb["cells"].insert(1, {"cell_type": "markdown", "metadata": {}, "source": note})
    return json.dumps(nb)


def say_what_is_missing(app) -> None:
    missing = app.config.ekfslam_unexecuted
    if not missing:
        return
    lines = "; ".join(
        f"{doc} needs {_datasets(numbers)} ({_fetch(numbers)})" for doc, numbers in missing.items()
    )
    if in_ci():
        raise ExtensionError(
            f"MRCLAM data missing, and CI renders every notebook executed: {lines} "
            "(set EKFSLAM_SHARED_DATA)"
        )
    logger.info(
        f"NOT EXECUTED (MRCLAM data not found; set EKFSLAM_SHARED_DATA), their pages say so: "
        f"{lines}",
        color="red",
    )


def mark_unexecuted(app, docname: str, source: list[str]) -> None:
    numbers = app.config.ekfslam_unexecuted.get(docname)
    if numbers:
        source[0] = marked(source[0], numbers)


def links_between_notebooks(app, doctree) -> None:
    outside = str(Path(app.config.ekfslam_notebooks).resolve()) + os.sep
    for node in doctree.findall(addnodes.pending_xref):
        target = node.get("reftarget", "")
        if node.get("refdomain") == "doc" and target.startswith(outside):
            node["reftarget"] = "notebooks/" + target[len(outside) :]


def setup(app):
    app.add_config_value("ekfslam_notebooks", "", "env")
    app.add_config_value("ekfslam_unexecuted", {}, "env")
    app.connect("builder-inited", say_what_is_missing)
    app.connect("source-read", mark_unexecuted)
    app.connect("doctree-read", links_between_notebooks)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
