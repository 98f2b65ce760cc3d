"""``python -m benchmarks grading [--students N] [--jobs J] [--repeats R]``: the lab's grading time.

From a fresh folder, as an instructor would: ``lab release`` of the whole lab (notebooks 02-07),
then N submissions (a third the solutions, a third the release's stubs, a third the solutions
with two mistakes typed in: 1a's vy row negated, 6b's innovation left unwrapped), graded by
``python -m ekfslam lab grade`` with ``--jobs J``, each exercise in its sandbox. It prints the
wall time of the whole run, the CPU seconds (the grader's processes and every sandbox, from the
kernel's accounting of the command's children) per submission, and the one-student grading
repeated R times (the first in a fresh process tree, the rest warm), median and range.
"""

from __future__ import annotations

import argparse
import json
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ekfslam.cli import args as ca
from ekfslam.teaching.make_lab import SOLUTIONS

NOTEBOOKS = ("02", "03", "04", "05", "06", "07")
RIGHT = {
    "02-wheels": "front-right and rear-left",
    "06-sigma": "larger",
    "06-error": "smaller",
    "07-size": "under 1 cm",
}
MISTAKES = {
    "02-robot-and-arena.ipynb": ("-w1 + w2 + w3 - w4", "w1 - w2 - w3 + w4"),
    "05-correction.ipynb": ("nu[1] = wrap_angle(nu[1])", "pass"),
}


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument("--students", type=ca.whole(3, 300), default=30, help="submissions (default 30)")
    p.add_argument("--jobs", type=ca.whole(1, 64), default=2, help="students at once (default 2)")
    p.add_argument("--repeats", type=ca.whole(1, 20), default=3, help="one-student gradings")
    p.set_defaults(func=cmd_lab)


SANDBOX_CPU = re.compile(r"\(its sandboxes: ([0-9.]+) s CPU\)")


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _grade(folder: Path, subs: str, jobs: int) -> tuple[float, float]:
    """Wall seconds of one `lab grade` and its CPU seconds: the grader's processes (the kernel's
    accounting of this command's children) plus what each sandbox reported at its close (its
    PID namespace keeps its processes out of that accounting)."""
    cpu, wall = _children_cpu(), time.perf_counter()
    command = [sys.executable, "-m", "ekfslam", "lab", "grade", subs, "--csv", f"{subs}.csv"]
    done = subprocess.run(
        [*command, "--jobs", str(jobs)], cwd=folder, check=True, capture_output=True, text=True
    )
    wall = time.perf_counter() - wall
    sandboxes = sum(float(m) for m in SANDBOX_CPU.findall(done.stdout))
    return wall, _children_cpu() - cpu + sandboxes


def _mistaken(text: str, name: str) -> str:
    old, new = MISTAKES.get(name, ("", ""))
    return text.replace(old, new) if old else text


def cmd_lab(args: argparse.Namespace) -> int:
    with tempfile.TemporaryDirectory(prefix="ekfslam-lab-bench-") as tmp:
        folder = Path(tmp)
        release = [sys.executable, "-m", "ekfslam", "lab", "release", "handout"]
        subprocess.run(release, cwd=folder, check=True, capture_output=True)
        names = sorted(p.name for p in (folder / "handout").glob("*.ipynb"))
        for i in range(args.students):
            student = folder / "subs" / f"student{i:02d}"
            student.mkdir(parents=True)
            kind = i % 3
            for name in names:
                if kind == 1:
                    shutil.copyfile(folder / "handout" / name, student / name)
                    continue
                text = (SOLUTIONS / name).read_text(encoding="utf-8")
                (student / name).write_text(text if kind == 0 else _mistaken(text, name), "utf-8")
            if kind != 1:
                (student / "lab-predictions.json").write_text(json.dumps(RIGHT), "utf-8")
        one = folder / "one" / "student00"
        shutil.copytree(folder / "subs" / "student00", one)
        singles = [_grade(folder, "one", 1) for _ in range(args.repeats)]
        wall, cpu = _grade(folder, "subs", args.jobs)
        grades = (folder / "subs.csv").read_text(encoding="utf-8").splitlines()
    totals = sorted({line.split(",")[-2] for line in grades[1:]})
    print(f"lab grade: {args.students} full submissions (notebooks 02-07), --jobs {args.jobs}")
    print(f"  wall {wall:.0f} s, CPU {cpu:.0f} s: {cpu / args.students:.1f} s CPU per submission")
    print(f"  totals seen: {', '.join(totals)} (of {len(grades[0].split(',')) - 3})")
    walls = [w for w, _ in singles]
    cpus = [c for _, c in singles]
    print(
        f"  one submission alone, {args.repeats} times: first {walls[0]:.1f} s wall "
        f"{cpus[0]:.1f} s CPU; median {statistics.median(walls):.1f} s wall "
        f"{statistics.median(cpus):.1f} s CPU (range {min(cpus):.1f}-{max(cpus):.1f})"
    )
    return 0
