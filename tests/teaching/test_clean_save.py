"""A notebook of the checkout saved from Jupyter is stored without outputs (clean_save)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import pytest

from ekfslam.teaching import clean_save

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "jupyter-config" / "ekfslam.json"


def _notebook() -> dict:
    return {
        "nbformat": 4,
        "nbformat_minor": 5,
        "metadata": {"language_info": {"name": "python", "version": "3.99.0"}, "widgets": {}},
        "cells": [
            {
                "cell_type": "code",
                "id": "a1",
                "metadata": {},
                "source": "print(1)",
                "execution_count": 3,
                "outputs": [{"output_type": "stream", "name": "stdout", "text": "1\n"}],
            },
            {"cell_type": "markdown", "id": "b2", "metadata": {}, "source": "# Title"},
        ],
    }


def _checkout(tmp_path: Path) -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "ekfslam"\n', encoding="utf-8")
    for folder in ("notebooks", "solutions", "elsewhere"):
        (tmp_path / folder).mkdir()
    return tmp_path


def test_a_checkouts_notebook_is_cleaned_and_no_other(tmp_path: Path) -> None:
    root = _checkout(tmp_path)
    assert clean_save.in_a_checkout(root / "notebooks" / "01.ipynb")
    assert clean_save.in_a_checkout(root / "solutions" / "02.ipynb")
    assert not clean_save.in_a_checkout(root / "elsewhere" / "01.ipynb")
    (root / "pyproject.toml").write_text('[project]\nname = "other"\n', encoding="utf-8")
    assert not clean_save.in_a_checkout(root / "notebooks" / "01.ipynb")


def test_cleaning_keeps_the_source_and_the_stored_language_version() -> None:
    stored = {"metadata": {"language_info": {"name": "python", "version": "3.11.7"}}}
    nb = clean_save.cleaned(_notebook(), stored)
    (code, text) = nb["cells"]
    assert (
        code["outputs"] == [] and code["execution_count"] is None and code["source"] == "print(1)"
    )
    assert text["source"] == "# Title" and "widgets" not in nb["metadata"]
    assert nb["metadata"]["language_info"]["version"] == "3.11.7"


def test_the_environment_installs_the_hook_for_every_jupyter_server() -> None:
    """The config that setup.py installs (a copy's data files, pip install -r requirements.txt)
    enables this server extension, which registers the hook."""
    config = json.loads(CONFIG.read_text(encoding="utf-8"))
    assert config["ServerApp"]["jpserver_extensions"] == {"ekfslam.teaching.clean_save": True}
    (point,) = clean_save._jupyter_server_extension_points()
    assert point["module"] == clean_save.__name__
    hooks = []
    server = SimpleNamespace(contents_manager=SimpleNamespace(register_pre_save_hook=hooks.append))
    clean_save._load_jupyter_server_extension(server)
    assert hooks == [clean_save.strip_outputs]
    setup = (ROOT / "setup.py").read_text(encoding="utf-8")
    assert '"etc/jupyter/jupyter_server_config.d", ["jupyter-config/ekfslam.json"]' in setup
    lines = (ROOT / "requirements.txt").read_text(encoding="utf-8").splitlines()
    assert "." in lines and "-e ." not in lines  # editable installs skip data files


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _call(url: str, token: str, method: str = "GET", body: dict | None = None) -> dict:
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(url, data=data, method=method)
    request.add_header("Authorization", f"token {token}")
    request.add_header("Content-Type", "application/json")
    with urllib.request.urlopen(request, timeout=10) as response:
        return json.loads(response.read() or b"{}")


@pytest.mark.slow
def test_a_jupyter_server_saves_a_checkouts_notebook_without_outputs(tmp_path: Path) -> None:
    """Regression: running a notebook in JupyterLab wrote its outputs into the checkout's
    output-free files. A real Jupyter server, configured as the environment is (its config
    folder holding what setup.py installs), saves two notebooks through its contents API."""
    root = _checkout(tmp_path / "checkout")
    config = tmp_path / "etc" / "jupyter"
    (config / "jupyter_server_config.d").mkdir(parents=True)
    shutil.copy(CONFIG, config / "jupyter_server_config.d" / "ekfslam.json")
    port, token = _free_port(), "ekfslam-test"
    env = os.environ | {"JUPYTER_CONFIG_PATH": str(config), "JUPYTER_RUNTIME_DIR": str(tmp_path)}
    command = [sys.executable, "-m", "jupyter_server", f"--ServerApp.root_dir={root}"]
    command += [f"--port={port}", f"--IdentityProvider.token={token}"]
    server = subprocess.Popen(
        [*command, "--ServerApp.open_browser=False", "--allow-root"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    base = f"http://127.0.0.1:{port}/api"
    try:
        for _ in range(120):
            try:
                _call(f"{base}/status", token)
                break
            except OSError:
                time.sleep(0.25)
        else:
            pytest.fail("the Jupyter server did not start")
        for folder in ("notebooks", "elsewhere"):
            model = {"type": "notebook", "format": "json", "content": _notebook()}
            _call(f"{base}/contents/{folder}/run.ipynb", token, "PUT", model)
    finally:
        server.terminate()
        server.wait(timeout=30)
    kept = json.loads((root / "notebooks" / "run.ipynb").read_text(encoding="utf-8"))
    assert kept["cells"][0]["outputs"] == [] and kept["cells"][0]["execution_count"] is None
    assert "".join(kept["cells"][0]["source"]) == "print(1)"
    other = json.loads((root / "elsewhere" / "run.ipynb").read_text(encoding="utf-8"))
    assert other["cells"][0]["outputs"] != []  # a notebook outside notebooks/ is the user's
