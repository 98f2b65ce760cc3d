"""`python -m benchmarks ...` as it runs from a checkout: a fresh interpreter, or in this process
(`tests/ekfslam_cli.py` runs every command line the tests drive; pytest puts this folder on
the path)."""

from __future__ import annotations

import functools

from tests.ekfslam_cli import main_of, run_module

#: ``python -m benchmarks ARGS`` from the checkout's root (a `subprocess.CompletedProcess`)
run_benchmarks_command = functools.partial(run_module, "benchmarks")
#: ``python -m benchmarks ARGV`` in this process: its exit status
benchmarks_main = main_of("benchmarks")
