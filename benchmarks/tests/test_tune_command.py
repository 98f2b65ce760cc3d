"""``python -m benchmarks tune``: the live panel's latency, its refusals before any work."""

from __future__ import annotations

from pathlib import Path

from benchmarks_cli import run_benchmarks_command


def test_tune_browser_against_a_folder_that_is_no_checkout_names_it(tmp_path: Path):
    out = run_benchmarks_command("tune", "--browser", "--against", str(tmp_path))
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        f"error: {tmp_path}: not a checkout of ekfslam (no ekfslam/__init__.py)"
    ]
    assert "Traceback" not in out.stderr
