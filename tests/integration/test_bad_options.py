"""Bad option values and output paths through the command line, as a user meets them.

Every case must end at parse time, before any work: exit status 2, ONE line on stderr that names
the option (or the path) and hints at --help, no traceback, nothing on stdout, and no output
file left behind. The cases run as concurrent subprocesses (``python -m ekfslam ...``, and for the
repository's studies and benchmarks ``python -m studies ...`` and ``python -m benchmarks ...``,
which parse with the same option types) from one module-scoped fixture with a thread pool, so
the file costs a few interpreter starts per core.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
RUN = REPO / "data" / "runs" / "octagon-2laps"

# Placeholders: {run} a copy of data/runs/octagon-2laps, {file} a regular file, {tmp} the
# scratch folder (also the working directory, so relative outputs land there), {dir} an
# existing folder named like a file (dir.png, dir.csv are folders too).
BAD_RUN = "run {run}"
SIM = "simulate --trajectory square --out {tmp}/sim"
BAG = "convert rosbag {tmp}/bag --out {tmp}/bagrun --twist-topic /odom --detections-topic /tf"
DETECT = "detect {run}"

#: The commands run by ``python -m studies`` and ``python -m benchmarks``; the rest are ekfslam's.
MODULE_OF = {
    "consistency": "studies",
    "vision-eval": "studies",
    "score-mrclam": "studies",
    "tune-mrclam": "studies",
    "budget": "studies",
    "bench": "benchmarks",
    "tune": "benchmarks",
}

#: name -> (arguments, a word the one line must contain, outputs that must not exist afterwards)
CASES: dict[str, tuple[str, str, tuple[str, ...]]] = {
    # run: noise and filter options
    "run sigma-range zero": (f"{BAD_RUN} --sigma-range 0", "--sigma-range", ()),
    "run sigma-range negative": (f"{BAD_RUN} --sigma-range -1", "--sigma-range", ()),
    "run sigma-x nan": (f"{BAD_RUN} --sigma-x nan", "--sigma-x", ()),
    "run sigma-y inf": (f"{BAD_RUN} --sigma-y inf", "--sigma-y", ()),
    "run sigma-theta -inf": (f"{BAD_RUN} --sigma-theta -inf", "--sigma-theta", ()),
    "run sigma-x huge": (f"{BAD_RUN} --sigma-x 1e200", "--sigma-x", ()),
    "run sigma-bearing over pi": (f"{BAD_RUN} --sigma-bearing 4", "--sigma-bearing", ()),
    "run sigma-x text": (f"{BAD_RUN} --sigma-x abc", "--sigma-x", ()),
    "run gate negative": (f"{BAD_RUN} --gate -1", "--gate", ()),
    "run gate nan": (f"{BAD_RUN} --gate nan", "--gate", ()),
    "run gate huge": (f"{BAD_RUN} --gate 1e300", "--gate", ()),
    "run iterations zero": (f"{BAD_RUN} --iterations 0", "--iterations", ()),
    "run iterations with fej": (
        f"{BAD_RUN} --linearization fej --iterations 2",
        "--iterations",
        (),
    ),
    "consistency iterations zero": ("consistency nees --iterations 0", "--iterations", ()),
    "run reinit-after negative": (f"{BAD_RUN} --reinit-after -2", "--reinit-after", ()),
    "run reinit-after one": (f"{BAD_RUN} --reinit-after 1", "--reinit-after", ()),
    "run reinit-after fraction": (f"{BAD_RUN} --reinit-after 2.5", "--reinit-after", ()),
    "run robot zero": (f"{BAD_RUN} --robot 0", "--robot", ()),
    "run robot six": (f"{BAD_RUN} --robot 6", "--robot", ()),
    "run init unknown": (f"{BAD_RUN} --init foo", "--init", ()),
    "run align unknown": (f"{BAD_RUN} --align foo", "--align", ()),
    "run unknown option": (f"{BAD_RUN} --sigma 1", "--sigma", ()),
    "run no folder": ("run", "required", ()),
    # run: --plot
    "run plot unknown format": (f"{BAD_RUN} --plot fig.xyz", "--plot", ("fig.xyz",)),
    "run plot no extension": (f"{BAD_RUN} --plot figure", "--plot", ("figure", "figure.png")),
    "run plot under a file": (f"{BAD_RUN} --plot {{file}}/fig.png", "--plot", ()),
    "run plot onto a folder": (f"{BAD_RUN} --plot {{dir}}.png", "--plot", ()),
    "run plot under a file, deeper": (f"{BAD_RUN} --plot {{file}}/a/b.pdf", "--plot", ()),
    # run: --animate
    "run animate unknown format": (f"{BAD_RUN} --animate a.avi", "--animate", ("a.avi",)),
    "run animate png": (f"{BAD_RUN} --animate a.png", "--animate", ("a.png",)),
    "run animate no extension": (f"{BAD_RUN} --animate movie", "--animate", ("movie",)),
    "run animate under a file": (f"{BAD_RUN} --animate {{file}}/a.gif", "--animate", ()),
    "run animate onto a folder": (f"{BAD_RUN} --animate {{dir}}.gif", "--animate", ()),
    "run animate frames one": (f"{BAD_RUN} --animate a.gif --frames 1", "--frames", ("a.gif",)),
    "run animate frames huge": (f"{BAD_RUN} --animate a.gif --frames 5000", "--frames", ("a.gif",)),
    "run animate frames fraction": (f"{BAD_RUN} --animate a.gif --frames 2.5", "--frames", ()),
    "run animate fps zero": (f"{BAD_RUN} --animate a.gif --fps 0", "--fps", ("a.gif",)),
    "run animate fps huge": (f"{BAD_RUN} --animate a.gif --fps 1000", "--fps", ("a.gif",)),
    "run animate fps nan": (f"{BAD_RUN} --animate a.gif --fps nan", "--fps", ("a.gif",)),
    "run fps without animate": (f"{BAD_RUN} --fps 5", "--fps", ()),
    "run frames without animate": (f"{BAD_RUN} --frames 5", "--frames", ()),
    # simulate
    "simulate laps zero": (f"{SIM} --laps 0", "--laps", ("sim",)),
    "simulate laps negative": (f"{SIM} --laps -3", "--laps", ("sim",)),
    "simulate laps huge": (f"{SIM} --laps 100000", "--laps", ("sim",)),
    "simulate laps fraction": (f"{SIM} --laps 2.5", "--laps", ("sim",)),
    "simulate size zero": (f"{SIM} --size 0", "--size", ("sim",)),
    "simulate size negative": (f"{SIM} --size -1", "--size", ("sim",)),
    "simulate size huge": (f"{SIM} --size 1e6", "--size", ("sim",)),
    "simulate size nan": (f"{SIM} --size nan", "--size", ("sim",)),
    "simulate octagon outside arena": (
        "simulate --trajectory octagon --size 1.2 --out {tmp}/sim",
        "--size",
        ("sim",),
    ),
    "simulate seed negative": (f"{SIM} --seed -1", "--seed", ("sim",)),
    "simulate start-error nan": (f"{SIM} --start-error 0 0 nan", "--start-error", ("sim",)),
    "simulate start-error far": (f"{SIM} --start-error 5 0 0", "--start-error", ("sim",)),
    "simulate start-error two values": (f"{SIM} --start-error 0 0", "--start-error", ("sim",)),
    "simulate wheel-scale negative": (
        f"{SIM} --wheel-scale-sigma -0.1",
        "--wheel-scale-sigma",
        ("sim",),
    ),
    "simulate wheel-scale huge": (f"{SIM} --wheel-scale-sigma 5", "--wheel-scale-sigma", ("sim",)),
    "simulate scenario unknown": (f"{SIM} --scenario perfect", "--scenario", ("sim",)),
    "simulate out is a file": ("simulate --trajectory square --out {file}", "--out", ()),
    "simulate out under a file": ("simulate --trajectory square --out {file}/r", "--out", ()),
    "simulate out not empty": ("simulate --trajectory square --out {run}", "--overwrite", ()),
    "simulate unknown trajectory": (
        "simulate --trajectory circle --out {tmp}/sim",
        "--trajectory",
        ("sim",),
    ),
    "simulate no out": ("simulate --trajectory square", "--out", ()),
    # fetch
    "fetch dataset 10": ("fetch mrclam 10", "1, 2, 3, 4, 5, 6, 7, 8, 9", ()),
    "fetch dataset 0": ("fetch mrclam 0", "number", ()),
    "fetch dataset text": ("fetch mrclam seven", "number", ()),
    "fetch unknown family": ("fetch kitti 1", "dataset", ()),
    "fetch cache is a file": ("fetch mrclam 7 --cache {file}", "--cache", ()),
    "fetch url scheme": ("fetch mrclam 7 --url ftp://example.org", "--url", ()),
    # convert mrclam
    "convert mrclam robot zero": (
        "convert mrclam {tmp} --robot 0 --out {tmp}/mr",
        "--robot",
        ("mr",),
    ),
    "convert mrclam robot text": (
        "convert mrclam {tmp} --robot x --out {tmp}/mr",
        "--robot",
        ("mr",),
    ),
    "convert mrclam out is a file": ("convert mrclam {tmp} --robot 1 --out {file}", "--out", ()),
    "convert unknown format": ("convert kitti x --out {tmp}/mr", "format", ("mr",)),
    # convert rosbag
    "rosbag pitch over 90 degrees": (f"{BAG} --camera-pitch 2", "--camera-pitch", ("bagrun",)),
    "rosbag bad regex": (f"{BAG} --tag-frame-pattern '('", "--tag-frame-pattern", ("bagrun",)),
    "rosbag wheel radius zero": (
        f"{BAG} --wheel-geometry 0 0.1 0.1",
        "--wheel-geometry",
        ("bagrun",),
    ),
    "rosbag mounting nan": (f"{BAG} --camera-mounting 0 0 nan", "--camera-mounting", ("bagrun",)),
    "rosbag start far away": (f"{BAG} --start 1e9 0 0", "--start", ("bagrun",)),
    "rosbag empty topic": (
        "convert rosbag {tmp}/bag --out {tmp}/bagrun --twist-topic /odom --detections-topic ''",
        "--detections-topic",
        ("bagrun",),
    ),
    "rosbag out is a file": (
        "convert rosbag {tmp}/bag --out {file} --twist-topic /odom --detections-topic /tf",
        "--out",
        (),
    ),
    # tum
    "tum out is a file": ("tum {run} --out {file}", "--out", ()),
    "tum robot nine": ("tum {run} --robot 9 --out {tmp}/tum", "--robot", ("tum",)),
    "tum sigma-range zero": (
        "tum {run} --sigma-range 0 --out {tmp}/tum",
        "--sigma-range",
        ("tum",),
    ),
    "tum gate inf": ("tum {run} --gate inf --out {tmp}/tum", "--gate", ("tum",)),
    # render-frames
    "render mounting yaw": (
        "render-frames {run} --out {tmp}/fr --mounting 0 0 9",
        "--mounting",
        ("fr",),
    ),
    "render mounting text": (
        "render-frames {run} --out {tmp}/fr --mounting 0 x 0",
        "--mounting",
        ("fr",),
    ),
    "render seed negative": ("render-frames {run} --out {tmp}/fr --seed -1", "--seed", ("fr",)),
    "render out is a file": ("render-frames {run} --out {file}", "--out", ()),
    "render out not empty": ("render-frames {run} --out {run}", "--overwrite", ()),
    # detect
    "detect incidence negative": (f"{DETECT} --max-incidence -5", "--max-incidence", ()),
    "detect incidence over 90": (f"{DETECT} --max-incidence 91", "--max-incidence", ()),
    "detect incidence nan": (f"{DETECT} --max-incidence nan", "--max-incidence", ()),
    "detect out under a file": (f"{DETECT} --out {{file}}/d.csv", "--out", ()),
    "detect out folder onto a file": (f"{DETECT} --out {{file}}", "--out", ()),
    "detect out onto a folder": (f"{DETECT} --out {{dir}}.csv", "--out", ()),
    "detect unknown detector": (f"{DETECT} --detector foo", "--detector", ()),
    # vision-eval
    "vision poses negative": ("vision-eval --poses -5", "--poses", ()),
    "vision poses zero": ("vision-eval --poses 0", "--poses", ()),
    "vision poses huge": ("vision-eval --poses 10000000", "--poses", ()),
    "vision blur negative": ("vision-eval --blur -1", "--blur", ()),
    "vision blur inf": ("vision-eval --blur inf", "--blur", ()),
    "vision seed negative": ("vision-eval --seed -3", "--seed", ()),
    "vision run missing": ("vision-eval --run {tmp}/missing", "--run", ()),
    # consistency
    "consistency outliers over 1": ("consistency outliers 2", "rate", ()),
    "consistency outliers negative": ("consistency outliers -0.1", "rate", ()),
    "consistency runs zero": ("consistency nees --runs 0", "--runs", ()),
    "consistency runs float": ("consistency nees --runs 1e3", "--runs", ()),
    "consistency gate negative": ("consistency nees --gate -1", "--gate", ()),
    "consistency wheel-noise nan": ("consistency nees --wheel-noise nan", "--wheel-noise", ()),
    "consistency plot gif": ("consistency nees --plot c.gif", "--plot", ("c.gif",)),
    "consistency plot under a file": ("consistency nees --plot {file}/c.png", "--plot", ()),
    "consistency long-run zero": ("consistency long-run --steps 0", "--steps", ()),
    "consistency association runs zero": ("consistency association --runs 0", "--runs", ()),
    "consistency gate-after zero": ("consistency outliers 0.1 --gate-after 0", "--gate-after", ()),
    "consistency robot nine": ("consistency mrclam --robots 9", "--robots", ()),
    # a MRCLAM dataset is named one way everywhere: its folder or its number 1-9
    "consistency mrclam dataset ten": ("consistency mrclam 10", "DATASET", ()),
    "score-mrclam dataset zero": ("score-mrclam 0", "DATASET", ()),
    "score-mrclam dataset missing folder": ("score-mrclam {tmp}/nowhere", "DATASET", ()),
    "score-mrclam linearization without association": (
        "score-mrclam 7 --linearization fej",
        "--linearization",
        (),
    ),
    "score-mrclam hypotheses without mht": (
        "score-mrclam 7 --association jcbb --hypotheses 4",
        "--hypotheses",
        (),
    ),
    "score-mrclam map-noise without association": (
        "score-mrclam 7 --map-noise none",
        "--map-noise",
        (),
    ),
    "score-mrclam map-noise unknown": (
        "score-mrclam 7 --association jcbb --map-noise x005",
        "--map-noise",
        (),
    ),
    "score-mrclam time-error without association": (
        "score-mrclam 7 --time-error shared",
        "--time-error",
        (),
    ),
    "score-mrclam time-error unknown": (
        "score-mrclam 7 --association jcbb --time-error both",
        "--time-error",
        (),
    ),
    "score-mrclam hypotheses too many": (
        "score-mrclam 7 --association mht --hypotheses 1000",
        "--hypotheses",
        (),
    ),
    "score-mrclam new-rule with nn": (
        "score-mrclam 7 --association nn --new-rule threshold",
        "--new-rule",
        (),
    ),
    "score-mrclam new-rule unknown": (
        "score-mrclam 7 --association jcbb --new-rule nis",
        "--new-rule",
        (),
    ),
    "run hypotheses zero": (f"{BAD_RUN} --association mht --hypotheses 0", "--hypotheses", ()),
    "run hypotheses not whole": (
        f"{BAD_RUN} --association mht --hypotheses 2.5",
        "--hypotheses",
        (),
    ),
    "run hypotheses with known ids": (f"{BAD_RUN} --hypotheses 4", "--hypotheses", ()),
    "run new-rule with nn": (f"{BAD_RUN} --association nn --new-rule density", "--new-rule", ()),
    "run new-rule unknown": (f"{BAD_RUN} --association jcbb --new-rule nis", "--new-rule", ()),
    "run time-error with known ids": (f"{BAD_RUN} --time-error shared", "--time-error", ()),
    "run time-error unknown": (
        f"{BAD_RUN} --association jcbb --time-error late",
        "--time-error",
        (),
    ),
    "run passes zero": (f"{BAD_RUN} --association jcbb --passes 0", "--passes", ()),
    "run passes too many": (f"{BAD_RUN} --association jcbb --passes 11", "--passes", ()),
    "run passes not whole": (f"{BAD_RUN} --association jcbb --passes 1.5", "--passes", ()),
    "run passes with known ids": (f"{BAD_RUN} --passes 2", "--passes", ()),
    "run passes with invariant": (
        f"{BAD_RUN} --association jcbb --linearization invariant --passes 2",
        "--passes",
        (),
    ),
    "score-mrclam passes without association": ("score-mrclam 7 --passes 2", "--passes", ()),
    "score-mrclam passes text": ("score-mrclam 7 --association jcbb --passes two", "--passes", ()),
    "score-mrclam passes with invariant": (
        "score-mrclam 7 --association jcbb --linearization invariant --passes 2",
        "--passes",
        (),
    ),
    "bench mrclam dataset twelve": ("bench --mrclam 12", "--mrclam", ()),
    "convert mrclam dataset ninety-nine": (
        "convert mrclam 99 --robot 1 --out {tmp}/mr99",
        "dataset",
        ("{tmp}/mr99",),
    ),
    "consistency two modes": ("consistency outliers 0.1 --steps 5", "--steps", ()),
    "consistency jobs zero": ("consistency nees --jobs 0", "--jobs", ()),
    "consistency dask without scheme": (
        "consistency outliers 0.1 --dask localhost:8786",
        "--dask",
        (),
    ),
    "consistency dask empty host": ("consistency association --dask tcp://", "--dask", ()),
    # bench
    "bench sizes negative": ("bench --sizes -5 --out {tmp}/bench", "--sizes", ("bench",)),
    "bench sizes zero": ("bench --sizes 0 --out {tmp}/bench", "--sizes", ("bench",)),
    "bench sizes huge": ("bench --sizes 100000 --out {tmp}/bench", "--sizes", ("bench",)),
    "bench sizes text": ("bench --sizes ten --out {tmp}/bench", "--sizes", ("bench",)),
    "bench repeats zero": ("bench --repeats 0 --out {tmp}/bench", "--repeats", ("bench",)),
    "bench repeats negative": ("bench --repeats -1 --out {tmp}/bench", "--repeats", ("bench",)),
    "bench out is a file": ("bench --out {file}", "--out", ()),
    "bench mrclam missing": (
        "bench --mrclam {tmp}/missing --out {tmp}/bench",
        "--mrclam",
        ("bench",),
    ),
    # the top level
    "unknown command": ("frobnicate", "frobnicate", ()),
}


def _tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bad-options")
    run = shutil.copytree(RUN, root / "run")
    (root / "afile").write_text("not a folder\n")
    for name in ("dir", "dir.png", "dir.csv", "dir.gif"):
        (root / name).mkdir()
    return {"tmp": root, "run": run, "file": root / "afile", "dir": root / "dir"}


@pytest.fixture(scope="module")
def outcomes(scratch) -> dict[str, subprocess.CompletedProcess]:
    """Every case's finished process, all run concurrently; the scratch tree before them."""
    root = scratch["tmp"]
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    env.pop("EKFSLAM_MRCLAM_URL", None)
    before = _tree(root)

    def run(args: str) -> subprocess.CompletedProcess:
        argv = shlex.split(args.format(**{k: str(v) for k, v in scratch.items()}))
        return subprocess.run(
            [sys.executable, "-m", MODULE_OF.get(argv[0], "ekfslam"), *argv],
            cwd=root,
            env=env,
            text=True,
            capture_output=True,
            timeout=300,
        )

    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as pool:
        done = dict(zip(CASES, pool.map(run, (c[0] for c in CASES.values())), strict=True))
    done["<tree>"] = (before, _tree(root))  # type: ignore[assignment]
    return done


def test_the_table_is_big_enough():
    assert len(CASES) >= 60
    commands = {args.split()[0] for args, _, _ in CASES.values()}
    assert commands >= {
        "run",
        "simulate",
        "fetch",
        "convert",
        "tum",
        "render-frames",
        "detect",
        "vision-eval",
        "consistency",
        "bench",
    }


@pytest.mark.parametrize("name", list(CASES))
def test_bad_option_ends_in_one_line_naming_it(outcomes, scratch, name):
    out = outcomes[name]
    _, word, leaves = CASES[name]
    assert out.returncode == 2, (out.stdout, out.stderr)
    assert "Traceback" not in out.stderr
    assert out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert word in lines[0], lines[0]
    assert "error:" in lines[0] and "--help" in lines[0], lines[0]
    for leaf in leaves:
        assert not (scratch["tmp"] / leaf).exists(), leaf


def test_no_case_left_any_file_behind(outcomes):
    before, after = outcomes["<tree>"]
    assert after == before
