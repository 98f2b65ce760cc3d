"""The checkout's notebooks stay stored without outputs when a student runs them in Jupyter.

A student who clones the repository and runs ``jupyter lab notebooks/`` saves the notebooks
back into the checkout; without this, every save wrote figures and tables into the output-free
files the tests check (and ``git pull`` then conflicted). This module is a Jupyter server
extension: installing the package (``pip install -r requirements.txt``, which installs a copy:
an editable install skips data files) puts ``etc/jupyter/jupyter_server_config.d/ekfslam.json``
into the environment, which enables it in every Jupyter server there (JupyterLab, Notebook,
Voila), and it registers `strip_outputs` as the server's pre-save hook. It clears what running
adds (outputs, execution counts, the widgets' state, the kernel's version) only in a notebook of
an ekfslam checkout's ``notebooks/`` or ``solutions/``; any other notebook (a release's
hand-out, the student's own) is saved as it is.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

#: the folders of a checkout whose notebooks are stored clean (tests/integration/test_notebooks.py)
CLEAN_FOLDERS = ("notebooks", "solutions")
_NAME = re.compile(r'^name\s*=\s*"ekfslam"\s*$', re.M)


def in_a_checkout(path: Path) -> bool:
    """True when `path` is a notebook in ``notebooks/`` or ``solutions/`` of an ekfslam checkout
    (its parent folder's pyproject.toml names the project ekfslam)."""
    folder = path.parent
    if folder.name not in CLEAN_FOLDERS:
        return False
    try:
        project = (folder.parent / "pyproject.toml").read_text(encoding="utf-8")
    except OSError:
        return False
    return bool(_NAME.search(project))


def cleaned(content: dict[str, Any], stored: dict[str, Any] | None = None) -> dict[str, Any]:
    """The notebook `content` (nbformat's dict) as the repository stores it: no outputs, no
    execution counts, no widget state; the language's version as `stored` (the file on disk) has
    it, so that a save changes only what the student edited. Changes `content` in place."""
    for cell in content.get("cells", []):
        if cell.get("cell_type") == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
    metadata = content.setdefault("metadata", {})
    metadata.pop("widgets", None)
    if stored is not None and "language_info" in stored.get("metadata", {}):
        metadata["language_info"] = stored["metadata"]["language_info"]
    return content


def strip_outputs(model: dict[str, Any], path: str, contents_manager: Any, **kwargs) -> None:
    """Jupyter's pre-save hook: a checkout's notebook is saved without what running added."""
    if model.get("type") != "notebook" or not isinstance(model.get("content"), dict):
        return
    root = Path(getattr(contents_manager, "root_dir", "."))
    os_path = (root / path.lstrip("/")).resolve()
    if not in_a_checkout(os_path):
        return
    try:
        stored = json.loads(os_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        stored = None
    cleaned(model["content"], stored)


def _jupyter_server_extension_points() -> list[dict[str, str]]:
    return [{"module": "ekfslam.teaching.clean_save"}]


def _load_jupyter_server_extension(serverapp: Any) -> None:
    serverapp.contents_manager.register_pre_save_hook(strip_outputs)
