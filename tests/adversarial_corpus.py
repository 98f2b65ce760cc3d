"""An adversarial corpus: inputs nobody listed, each with the answer that is right for it.

Written for issue 27 as a third party writing new bad inputs would (after two held-out corpora
found 3 of 149 and 34 of 215 wrong): the Python API given the wrong things, output targets that
cannot be written, signals in the middle of a write, files that are each fine but wrong together,
and a reader's worth of encodings, BOMs, line ends, unicode digits, duplicate headers, FIFOs,
device links and huge lines. Every case says what is right:

- refused: exit status 2 (or our exception), ONE line naming the input (file and line, the
  argument or the option) with a word saying what is wrong, no traceback, nothing written;
- accepted: exit 0 with the same results as the clean input (a BOM, CRLF, -0.0 change nothing);
- warned: exit 0 and a ``warning:`` line naming the file and the line;
- interrupted: exit 130 (SIGINT) or 143 (SIGTERM), one line, no ``.partial`` file left.

``python tests/adversarial_corpus.py`` scores whichever ekfslam is on the path (each case in its
own process, with a time limit): ``right N of M`` per family and why each wrong case is wrong.
``--only TEXT`` runs the cases whose name holds TEXT. tests/integration/test_adversarial_corpus.py
runs every case as a test. MRCLAM cases need Dataset 7 (EKFSLAM_SHARED_DATA), and skip without it.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import dataclasses
import importlib
import io
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SEED_RUN = REPO / "data" / "runs" / "square-2laps"
FRAMES_RUN = REPO / "data" / "runs" / "square-1lap-frames"
FAMILIES = ("api", "output", "signal", "plausibility", "file", "option")

Check = Callable[[Path], "str | None"]


@dataclass(frozen=True)
class Case:
    """One input and its right answer: `check(folder)` builds it in an empty `folder`, runs it,
    and returns None when ekfslam answered right, else why not."""

    name: str
    family: str
    check: Check
    needs: str = ""  # "mrclam": Dataset 7; "subprocess": must run in its own process


CASES: dict[str, Case] = {}


def case(name: str, family: str, needs: str = "") -> Callable[[Check], Check]:
    def register(check: Check) -> Check:
        assert name not in CASES, name
        CASES[name] = Case(name, family, check, needs)
        return check

    return register


def add(name: str, family: str, check: Check, needs: str = "") -> None:
    case(name, family, needs)(check)


# =============================================================================================
# Running ekfslam and judging what it did


@dataclass(frozen=True)
class Ran:
    code: int
    out: str
    err: str


#: Run the command line in this process (the tests: no interpreter start per case) rather than
#: in a fresh one (the score: every case isolated). Cases that patch ekfslam (`pre`) always
#: run in a fresh process, and so do the signal cases.
IN_PROCESS = False


def cli(*argv: str, cwd: Path = REPO, timeout: float = 300, pre: str = "") -> Ran:
    """``python -m ekfslam ARGV`` in a fresh process (`pre`: Python run first, e.g. a patch).

    ``bench`` never runs its benchmarks here (a corpus must not load the machine): they are
    replaced by a stub, so a bench command that is not refused ends at once.
    """
    if argv[:1] == ("bench",) and BENCH_STUB not in pre:
        pre = BENCH_STUB + pre
    module = _module(argv)
    if IN_PROCESS and not pre:
        return _in_process(argv, cwd)
    code = (
        [
            "-c",
            f"{pre}\nimport sys, runpy; sys.argv = ['{module}', *sys.argv[1:]]; "
            f"runpy.run_module('{module}', run_name='__main__')",
        ]
        if pre
        else ["-m", module]
    )
    env = _env()
    try:
        p = subprocess.run(
            [sys.executable, *code, *argv],
            cwd=cwd,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return Ran(-1, "", f"timed out after {timeout:g} s")
    return Ran(p.returncode, p.stdout, p.stderr)


def _module(argv: Sequence[str]) -> str:
    """The command line a command belongs to: the package's, or the repository's benchmarks
    or studies (they moved out of the package, issue 24)."""
    from benchmarks.__main__ import COMMANDS as BENCHMARKS
    from studies.__main__ import COMMANDS as STUDIES

    command = argv[0] if argv else ""
    return "benchmarks" if command in BENCHMARKS else "studies" if command in STUDIES else "ekfslam"


def _env() -> dict[str, str]:
    """The environment a command runs in: no display, and the checkout on the path (the
    repository's benchmarks/ and studies/ run from it, as their READMEs say)."""
    path = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": path}


def _in_process(argv: tuple[str, ...], cwd: Path) -> Ran:
    """`ekfslam.cli.main.main(argv)` here, its output captured; an exception that escapes it
    is a traceback, as the user would see one."""
    from ekfslam.cli.main import main

    table = {}
    module = _module(argv)
    if module != "ekfslam":
        commands = importlib.import_module(f"{module}.__main__").COMMANDS
        table = {"commands": commands, "prog": f"python -m {module}"}
    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv), **table)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except Exception:
            err.write(traceback.format_exc())
            code = 1
    return Ran(code, out.getvalue(), err.getvalue())


def _lines(text: str) -> list[str]:
    return [ln for ln in text.strip().splitlines() if ln.strip()]


def refused(r: Ran, where: str | None = None, word: str | None = None, code: int = 2) -> str | None:
    """Exit `code`, one stderr line (ours or the parser's) naming `where`, saying `word`."""
    if "Traceback" in r.err:
        return "traceback: " + _tail(r.err)
    if r.code != code:
        return f"exit {r.code}, expected {code}: " + _tail(r.err or r.out)
    lines = _lines(r.err)
    if len(lines) != 1:
        return f"{len(lines)} lines on stderr: " + _tail(r.err)
    line = lines[0]
    if not (line.startswith("error: ") or ": error: " in line):
        return "not an error line: " + line[:300]
    if where is not None and where not in line:
        return f"does not name {where!r}: " + line[:300]
    if word is not None and word.lower() not in line.lower():
        return f"does not say {word!r}: " + line[:300]
    if len(line) > 600:
        return f"a {len(line)}-character line"
    return None


def interrupted(r: Ran, code: int) -> str | None:
    """Exit `code` (128 + the signal) and one line on stderr, no traceback."""
    if "Traceback" in r.err:
        return "traceback: " + _tail(r.err)
    if r.code != code:
        return f"exit {r.code}, expected {code}: " + _tail(r.err or r.out)
    lines = _lines(r.err)
    if len(lines) != 1:
        return f"{len(lines)} lines on stderr: " + _tail(r.err)
    return None


def warned(r: Ran, where: str, word: str) -> str | None:
    """Exit 0 and a ``warning:`` line naming `where` and saying `word`."""
    if "Traceback" in r.err or r.code != 0:
        return f"exit {r.code}: " + _tail(r.err)
    hits = [ln for ln in _lines(r.err) if ln.startswith("warning:")]
    if not any(where in ln and word.lower() in ln.lower() for ln in hits):
        return f"no warning naming {where!r} with {word!r}: " + _tail(r.err or "(nothing)")
    return None


def accepted(r: Ran) -> str | None:
    if "Traceback" in r.err:
        return "traceback: " + _tail(r.err)
    if r.code != 0:
        return f"exit {r.code}: " + _tail(r.err)
    return None


def same_output(r: Ran, clean: Ran) -> str | None:
    """Accepted, printing what the clean input printed (timings and paths aside)."""
    problem = accepted(r)
    if problem is not None:
        return problem
    mine, theirs = _results(r.out), _results(clean.out)
    if mine != theirs:
        return f"results differ from the clean input's: {mine[:3]} vs {theirs[:3]}"
    return None


def _results(text: str) -> list[str]:
    drop = ("replay ", "figure written", "wrote ", "detections:")
    return [ln for ln in _lines(text) if not ln.startswith(drop) and "/" not in ln]


def _tail(text: str) -> str:
    return " | ".join(_lines(text)[-3:])[:400]


def raises(call: Callable[[], object], *words: str, kind: type = ValueError) -> str | None:
    """The call raises one of our errors that is a `kind` and says each of `words`."""
    from ekfslam.errors import EkfSlamError

    try:
        with np.errstate(all="ignore"):
            value = call()
    except EkfSlamError as exc:
        if not isinstance(exc, kind):
            return f"{type(exc).__name__} is not a {kind.__name__}: {exc}"
        text = str(exc)
        missing = [w for w in words if w.lower() not in text.lower()]
        if missing:
            return f"{type(exc).__name__} does not say {missing}: {text[:300]}"
        if "\n" in text.strip() or len(text) > 600:
            return f"a message of {len(text)} characters over lines: {text[:200]}"
        return None
    except Exception as exc:  # not ours: what the issue calls "from deep inside"
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return (
            f"{type(exc).__name__} from {Path(where.filename).name}:{where.lineno}: "
            f"{str(exc)[:200]}"
        )
    return f"no error; returned {str(value)[:120]}"


def returns(call: Callable[[], object], same: Callable[[], object]) -> str | None:
    """The call works and gives what the clean call gives."""
    try:
        with np.errstate(all="ignore"):
            got, want = call(), same()
    except Exception as exc:
        return f"{type(exc).__name__}: {str(exc)[:200]}"
    try:
        np.testing.assert_allclose(np.asarray(got, dtype=float), np.asarray(want, dtype=float))
    except (AssertionError, TypeError, ValueError) as exc:
        return f"differs from the clean call's result: {str(exc)[:200]}"
    return None


def leftovers(folder: Path) -> list[str]:
    """Temporary files a writer left behind anywhere under `folder`."""
    return sorted(str(p) for p in folder.rglob("*") if ".partial" in p.name)


# =============================================================================================
# Inputs: a clean run folder, a small MRCLAM dataset, a frames run, a ROS 2 bag

_CACHE: dict[str, Path] = {}
CACHE_DIR = Path(os.environ.get("EKFSLAM_CORPUS_CACHE", "/tmp/ekfslam-corpus-cache"))


def _cached(name: str, make: Callable[[Path], None]) -> Path:
    """A clean input made once per machine (under `CACHE_DIR`), copied for each case."""
    if name in _CACHE:
        return _CACHE[name]
    path = CACHE_DIR / name
    if not path.exists():
        tmp = CACHE_DIR / f".{name}.{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        make(tmp)
        try:
            tmp.rename(path)
        except OSError:  # another process made it first
            shutil.rmtree(tmp, ignore_errors=True)
    _CACHE[name] = path
    return path


def _make_run(tmp: Path) -> None:
    from ekfslam import SimulationConfig, simulate, write_run

    write_run(simulate(SimulationConfig(trajectory="square", laps=1, seed=1)), tmp / "run")


def clean_run() -> Path:
    """The clean one-lap square run (our format) every run case starts from."""
    return _cached("run", _make_run) / "run"


def run_folder(folder: Path) -> Path:
    """A copy of `clean_run()` in `folder`/run."""
    dest = folder / "run"
    shutil.copytree(clean_run(), dest)
    return dest


def mrclam_folder(folder: Path) -> Path:
    """Dataset 7's robot 1, its first 400 odometry lines and what falls within them (CRLF kept)."""
    from ekfslam.logs.mrclam.load import find_dataset

    def make(tmp: Path) -> None:
        src = find_dataset(7)
        out = tmp / "MRCLAM_Dataset7"
        out.mkdir()
        for name in ("Barcodes.dat", "Landmark_Groundtruth.dat"):
            shutil.copy(src / name, out / name)
        odometry = (src / "Robot1_Odometry.dat").read_bytes().split(b"\r\n")[:400]
        end = float(odometry[-1].split()[0])
        (out / "Robot1_Odometry.dat").write_bytes(b"\r\n".join(odometry) + b"\r\n")
        for kind in ("Measurement", "Groundtruth"):
            lines = (src / f"Robot1_{kind}.dat").read_bytes().split(b"\r\n")
            kept = [
                ln for ln in lines if ln.startswith(b"#") or (ln and float(ln.split()[0]) <= end)
            ]
            (out / f"Robot1_{kind}.dat").write_bytes(b"\r\n".join(kept) + b"\r\n")
        # robot 2's measurements over the same time, to mix into robot 1's
        lines = (src / "Robot2_Measurement.dat").read_bytes().split(b"\r\n")
        start = float(odometry[-400 + 5].split()[0]) if len(odometry) > 5 else 0.0
        kept = [ln for ln in lines if ln and not ln.startswith(b"#")]
        kept = [ln for ln in kept if start <= float(ln.split()[0]) <= end]
        (tmp / "robot2-measurements.dat").write_bytes(b"\r\n".join(kept) + b"\r\n")

    src = _cached("mrclam", make)
    dest = folder / "MRCLAM_Dataset7"
    shutil.copytree(src / "MRCLAM_Dataset7", dest)
    shutil.copy(src / "robot2-measurements.dat", folder / "robot2-measurements.dat")
    return dest


def frames_folder(folder: Path) -> Path:
    dest = folder / "frames-run"
    shutil.copytree(FRAMES_RUN, dest)
    return dest


def rosbag_folder(folder: Path) -> Path:
    """A ROS 2 bag: /odom (Odometry, 0.2 m/s) at 10 Hz for 3 s and /tf with tag_3 at 2 Hz."""

    def make(tmp: Path) -> None:
        from rosbags.rosbag2 import Writer
        from rosbags.typesys import Stores, get_typestore

        ts = get_typestore(Stores.ROS2_HUMBLE)
        T = ts.types

        def header(t: float, frame: str):
            sec = math.floor(t)
            stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))
            return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)

        def vec(x=0.0, y=0.0, z=0.0):
            return T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

        quat = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
        with Writer(tmp / "bag", version=9) as w:
            odom = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
            tf = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
            for k in range(30):
                t = 100.0 + 0.1 * k
                twist = T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](linear=vec(0.2), angular=vec(z=0.1)),
                    covariance=np.zeros(36),
                )
                pose = T["geometry_msgs/msg/PoseWithCovariance"](
                    pose=T["geometry_msgs/msg/Pose"](
                        position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                        orientation=quat,
                    ),
                    covariance=np.zeros(36),
                )
                msg = T["nav_msgs/msg/Odometry"](
                    header=header(t, "odom"), child_frame_id="base", pose=pose, twist=twist
                )
                w.write(odom, round(t * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))
                if k % 5 == 0:
                    tr = T["geometry_msgs/msg/TransformStamped"](
                        header=header(t, "camera"),
                        child_frame_id="tag_3",
                        transform=T["geometry_msgs/msg/Transform"](
                            translation=vec(0.1, 0.0, 1.5), rotation=quat
                        ),
                    )
                    m = T["tf2_msgs/msg/TFMessage"](transforms=[tr])
                    w.write(tf, round(t * 1e9) + 1, ts.serialize_cdr(m, m.__msgtype__))

    dest = folder / "bag"
    shutil.copytree(_cached("rosbag", make) / "bag", dest)
    return dest


ROSBAG_ARGS = ("--twist-topic", "/odom", "--detections-topic", "/tf")


def edit_lines(path: Path, edit: Callable[[list[str]], list[str]], newline: str = "\n") -> None:
    text = path.read_text(encoding="utf-8")
    path.write_text(newline.join(edit(text.splitlines())) + newline, encoding="utf-8")


def edit_column(path: Path, column: str, edit: Callable[[int, str], str]) -> None:
    """Rewrite one column of a run-format CSV: edit(row index, text) -> new text."""

    def change(lines: list[str]) -> list[str]:
        j = lines[0].split(",").index(column)
        out = [lines[0]]
        for i, line in enumerate(lines[1:]):
            cells = line.split(",")
            cells[j] = edit(i, cells[j])
            out.append(",".join(cells))
        return out

    edit_lines(path, change)


def dat_rows(path: Path) -> list[bytes]:
    return path.read_bytes().split(b"\r\n")


def data_index(lines: list[bytes], k: int) -> int:
    """The index in `lines` of the k-th data line (not a # header, not empty)."""
    seen = -1
    for i, ln in enumerate(lines):
        if ln and not ln.startswith(b"#"):
            seen += 1
            if seen == k:
                return i
    raise IndexError(k)


# =============================================================================================
# Family 1: the Python API checks what it is given


def _api():
    import ekfslam

    return ekfslam


_STATE: dict[str, object] = {}


def seed_run():
    if "run" not in _STATE:
        _STATE["run"] = _api().read_run(SEED_RUN)
    return _STATE["run"]


def seed_result():
    if "result" not in _STATE:
        _STATE["result"] = _api().replay(seed_run())
    return _STATE["result"]


def geometry():
    return _api().MecanumGeometry()


def ekf():
    return _api().EKFSLAM([0.0, 0.0, 0.0])


def _q():
    return np.diag([0.03**2, 0.03**2])


def _r3():
    return np.diag([1e-4, 1e-4, 1e-4])


TWO = {0: (0.0, 0.0), 1: (1.0, 0.0), 2: (0.0, 1.0)}

API: dict[str, Callable[[Path], str | None]] = {
    # read_run
    "read_run(None)": lambda f: raises(lambda: _api().read_run(None), "folder", kind=TypeError),
    "read_run(123)": lambda f: raises(lambda: _api().read_run(123), "folder", kind=TypeError),
    "read_run('')": lambda f: raises(lambda: _api().read_run(""), "empty"),
    "read_run(bytes path)": lambda f: raises(
        lambda: _api().read_run(bytes(SEED_RUN)), "folder", kind=TypeError
    ),
    "read_run(a RunLog)": lambda f: raises(
        lambda: _api().read_run(seed_run()), "folder", kind=TypeError
    ),
    "read_run(detections='x')": lambda f: raises(
        lambda: _api().read_run(SEED_RUN, detections="x"), "detections", kind=TypeError
    ),
    "read_run(str) == read_run(Path)": lambda f: returns(
        lambda: _api().read_run(str(SEED_RUN)).controls.values,
        lambda: _api().read_run(SEED_RUN).controls.values,
    ),
    # replay
    "replay(a path string)": lambda f: raises(
        lambda: _api().replay(str(SEED_RUN)), "run", "read_run", kind=TypeError
    ),
    "replay(None)": lambda f: raises(lambda: _api().replay(None), "run", kind=TypeError),
    "replay(noise=dict)": lambda f: raises(
        lambda: _api().replay(seed_run(), {"sigma_x": 0.1}), "noise", "NoiseConfig", kind=TypeError
    ),
    "replay(noise=FilterConfig)": lambda f: raises(
        lambda: _api().replay(seed_run(), _api().FilterConfig()), "noise", kind=TypeError
    ),
    "replay(config=dict)": lambda f: raises(
        lambda: _api().replay(seed_run(), config={"gate": 9.0}), "config", kind=TypeError
    ),
    "replay(start 2 numbers)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=[0.0, 0.0]), "start.pose"
    ),
    "replay(start strings)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=["0", "0", "0"]), "start.pose", kind=TypeError
    ),
    "replay(start NaN)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=[math.nan, 0.0, 0.0]), "start.pose"
    ),
    "replay(Start covariance 2x2)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=_api().Start(covariance=np.eye(2))),
        "start.covariance",
    ),
    "replay(Start covariance negative definite)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=_api().Start(covariance=-0.01 * np.eye(3))),
        "start.covariance",
    ),
    "replay(Start covariance not symmetric)": lambda f: raises(
        lambda: _api().replay(
            seed_run(),
            start=_api().Start(covariance=[[1e-4, 1e-3, 0], [0, 1e-4, 0], [0, 0, 1e-4]]),
        ),
        "start.covariance",
        "symmetric",
    ),
    "replay(Start covariance NaN)": lambda f: raises(
        lambda: _api().replay(seed_run(), start=_api().Start(covariance=np.full((3, 3), math.nan))),
        "start.covariance",
    ),
    "replay(association='jcbb')": lambda f: raises(
        lambda: _api().replay(seed_run(), association="jcbb"), "association", kind=TypeError
    ),
    "HiddenIds(passes='2')": lambda f: raises(lambda: _api().HiddenIds(passes="2"), "passes"),
    "replay(Start zero covariance) == replay()": lambda f: returns(
        lambda: _api().replay(seed_run(), start=_api().Start(covariance=np.zeros((3, 3)))).mu,
        lambda: seed_result().mu,
    ),
    "replay(start tuple) == replay()": lambda f: returns(
        lambda: _api().replay(seed_run(), start=tuple(seed_run().meta.nominal_start)).mu,
        lambda: seed_result().mu,
    ),
    "replay(run with NaN wheel speeds)": lambda f: raises(
        lambda: _api().replay(_with_controls(seed_run(), 5, 0, math.nan)), "controls"
    ),
    "replay(run with 1e300 wheel speed)": lambda f: raises(
        lambda: _api().replay(_with_controls(seed_run(), 5, 0, 1e300)), "controls"
    ),
    # write_run
    "write_run(None, folder)": lambda f: raises(
        lambda: _api().write_run(None, f / "out"), "run", kind=TypeError
    ),
    "write_run(a path, folder)": lambda f: raises(
        lambda: _api().write_run(str(SEED_RUN), f / "out"), "run", kind=TypeError
    ),
    "write_run(run, None)": lambda f: raises(
        lambda: _api().write_run(seed_run(), None), "folder", kind=TypeError
    ),
    "write_run(run, '')": lambda f: raises(lambda: _api().write_run(seed_run(), ""), "empty"),
    "write_run(run, under /proc)": lambda f: _our_error(
        lambda: _api().write_run(seed_run(), "/proc/ekfslam-corpus-run"), "/proc/ekfslam-corpus-run"
    ),
    "write_run(overwrite='yes')": lambda f: raises(
        lambda: _api().write_run(seed_run(), f / "out", overwrite="yes"),
        "overwrite",
        kind=TypeError,
    ),
    # simulate and its config
    "simulate(dict)": lambda f: raises(
        lambda: _api().simulate({"trajectory": "square"}), "SimulationConfig", kind=TypeError
    ),
    "simulate(arena=None)": lambda f: raises(
        lambda: _api().simulate(arena=None), "arena", kind=TypeError
    ),
    "SimulationConfig(laps='2')": lambda f: raises(
        lambda: _api().SimulationConfig(laps="2"), "laps", kind=TypeError
    ),
    "SimulationConfig(seed=-1)": lambda f: raises(lambda: _api().SimulationConfig(seed=-1), "seed"),
    "SimulationConfig(seed=1.5)": lambda f: raises(
        lambda: _api().SimulationConfig(seed=1.5), "seed", kind=TypeError
    ),
    "SimulationConfig(size=nan)": lambda f: raises(
        lambda: _api().SimulationConfig(size=math.nan), "size"
    ),
    "SimulationConfig(start_error 2 numbers)": lambda f: raises(
        lambda: _api().SimulationConfig(start_error=(0.1, 0.1)), "start_error"
    ),
    # summarize, align, ate_rmse
    "summarize(method='meanDistance')": lambda f: raises(
        lambda: _api().summarize(seed_run(), seed_result(), method="meanDistance"), "method"
    ),
    "summarize(method=None)": lambda f: raises(
        lambda: _api().summarize(seed_run(), seed_result(), method=None), "method"
    ),
    "summarize(a path, result)": lambda f: raises(
        lambda: _api().summarize(str(SEED_RUN), seed_result()), "run", kind=TypeError
    ),
    "summarize(run, None)": lambda f: raises(
        lambda: _api().summarize(seed_run(), None), "result", kind=TypeError
    ),
    "summarize(result, run) swapped": lambda f: raises(
        lambda: _api().summarize(seed_result(), seed_run()), "run", kind=TypeError
    ),
    "align(method='procrustes')": lambda f: raises(
        lambda: _api().align(TWO, TWO, method="procrustes"), "method"
    ),
    "align(lists, not mappings)": lambda f: raises(
        lambda: _api().align([(0, 0), (1, 0)], [(0, 0), (1, 0)]), "mapping", kind=TypeError
    ),
    "align(points with 3 coordinates)": lambda f: raises(
        lambda: _api().align({0: (0, 0, 0), 1: (1, 0, 0), 2: (0, 1, 0)}, TWO), "2 numbers"
    ),
    "align(NaN point)": lambda f: raises(
        lambda: _api().align({0: (math.nan, 0), 1: (1, 0), 2: (0, 1)}, TWO), "finite"
    ),
    "align(string ids)": lambda f: raises(
        lambda: _api().align({"a": (0, 0), "b": (1, 0)}, TWO), "integer"
    ),
    "align(every true tag at one point)": lambda f: raises(
        lambda: _api().align(TWO, {0: (1.0, 1.0), 1: (1.0, 1.0), 2: (1.0, 1.0)}), "one point"
    ),
    "align(every estimate at one point)": lambda f: raises(
        lambda: _api().align({0: (0.0, 0.0), 1: (0.0, 0.0), 2: (0.0, 0.0)}, TWO), "one point"
    ),
    "align_least_squares((3, 3) arrays)": lambda f: raises(
        lambda: _api().align_least_squares(np.zeros((3, 3)), np.zeros((3, 3))), "(N, 2)"
    ),
    "align_mean_distance(shapes differ)": lambda f: raises(
        lambda: _api().align_mean_distance([[0, 0], [1, 1]], [[0, 0]]), "shape"
    ),
    "ate_rmse(result, None)": lambda f: raises(
        lambda: _api().ate_rmse(seed_result(), None), "groundtruth", kind=TypeError
    ),
    "ate_rmse(None, truth)": lambda f: raises(
        lambda: _api().ate_rmse(None, seed_run().groundtruth), "result", kind=TypeError
    ),
    "ate_rmse(result, run)": lambda f: raises(
        lambda: _api().ate_rmse(seed_result(), seed_run()), "groundtruth", kind=TypeError
    ),
    # kinematics
    "wheels_to_twist(NaN)": lambda f: raises(
        lambda: _api().wheels_to_twist([math.nan, 0, 0, 0], geometry()), "wheels"
    ),
    "wheels_to_twist(inf)": lambda f: raises(
        lambda: _api().wheels_to_twist([[1, 1, 1, 1], [math.inf, 0, 0, 0]], geometry()), "wheels"
    ),
    "wheels_to_twist(3 speeds)": lambda f: raises(
        lambda: _api().wheels_to_twist([1, 2, 3], geometry()), "wheels", "4"
    ),
    "wheels_to_twist(geometry None)": lambda f: raises(
        lambda: _api().wheels_to_twist([1, 2, 3, 4], None), "geometry", kind=TypeError
    ),
    "wheels_to_twist(a string)": lambda f: raises(
        lambda: _api().wheels_to_twist("1,2,3,4", geometry()), "wheels", kind=TypeError
    ),
    "twist_to_wheels(2 numbers)": lambda f: raises(
        lambda: _api().twist_to_wheels([1, 2], geometry()), "twist", "3"
    ),
    "twist_to_wheels(NaN)": lambda f: raises(
        lambda: _api().twist_to_wheels([0.1, 0, math.nan], geometry()), "twist"
    ),
    "twist_to_wheels(geometry dict)": lambda f: raises(
        lambda: _api().twist_to_wheels([0.1, 0, 0], {"wheel_radius": 0.03}),
        "geometry",
        kind=TypeError,
    ),
    "wheels_to_twist(float32) == float64": lambda f: returns(
        lambda: _api().wheels_to_twist(np.array([1, 2, 3, 4], dtype=np.float32), geometry()),
        lambda: _api().wheels_to_twist(np.array([1.0, 2.0, 3.0, 4.0]), geometry()),
    ),
    "MecanumGeometry(wheel_radius='0.03')": lambda f: raises(
        lambda: _api().MecanumGeometry(wheel_radius="0.03"), "wheel_radius", kind=TypeError
    ),
    # configs
    "NoiseConfig(sigma_range='0.03')": lambda f: raises(
        lambda: _api().NoiseConfig(sigma_range="0.03"), "sigma_range", kind=TypeError
    ),
    "NoiseConfig(sigma_x=None)": lambda f: raises(
        lambda: _api().NoiseConfig(sigma_x=None), "sigma_x", kind=TypeError
    ),
    "NoiseConfig(sigma_bearing=-0.1)": lambda f: raises(
        lambda: _api().NoiseConfig(sigma_bearing=-0.1), "sigma_bearing"
    ),
    "NoiseConfig(R_per_step 2x2)": lambda f: raises(
        lambda: _api().NoiseConfig(R_per_step=((1.0, 0.0), (0.0, 1.0))), "R_per_step"
    ),
    "NoiseConfig(R_per_step negative)": lambda f: raises(
        lambda: _api().NoiseConfig(R_per_step=tuple(map(tuple, -np.eye(3)))), "R_per_step"
    ),
    "NoiseConfig(np.float64) accepted": lambda f: returns(
        lambda: _api().NoiseConfig(sigma_x=np.float64(0.05)).sigma_x, lambda: 0.05
    ),
    "FilterConfig(gate='9.21')": lambda f: raises(
        lambda: _api().FilterConfig(gate="9.21"), "gate", kind=TypeError
    ),
    "FilterConfig(gate=-1)": lambda f: raises(lambda: _api().FilterConfig(gate=-1.0), "gate"),
    "FilterConfig(linearization='ekf')": lambda f: raises(
        lambda: _api().FilterConfig(linearization="ekf"), "linearization"
    ),
    "FilterConfig(reinit_after=2.5)": lambda f: raises(
        lambda: _api().FilterConfig(reinit_after=2.5), "reinit_after", kind=TypeError
    ),
    "FilterConfig(initial_capacity='16')": lambda f: raises(
        lambda: _api().FilterConfig(initial_capacity="16"), "initial_capacity", kind=TypeError
    ),
    "default_noise(None)": lambda f: raises(
        lambda: _api().default_noise(None), "run", kind=TypeError
    ),
    # the filter
    "EKFSLAM(pose of 2)": lambda f: raises(lambda: _api().EKFSLAM([0.0, 0.0]), "pose"),
    "EKFSLAM(pose a string)": lambda f: raises(
        lambda: _api().EKFSLAM("0 0 0"), "pose", kind=TypeError
    ),
    "EKFSLAM(pose_covariance 2x2)": lambda f: raises(
        lambda: _api().EKFSLAM([0, 0, 0], np.eye(2)), "pose_covariance"
    ),
    "EKFSLAM(pose_covariance negative definite)": lambda f: raises(
        lambda: _api().EKFSLAM([0, 0, 0], -np.eye(3)), "pose_covariance"
    ),
    "EKFSLAM(config dict)": lambda f: raises(
        lambda: _api().EKFSLAM([0, 0, 0], config={"gate": None}), "config", kind=TypeError
    ),
    "EKFSLAM.predict(u of 2)": lambda f: raises(lambda: ekf().predict([1, 2], _r3()), "u"),
    "EKFSLAM.predict(u NaN)": lambda f: raises(lambda: ekf().predict([math.nan, 0, 0], _r3()), "u"),
    "EKFSLAM.predict(R negative)": lambda f: raises(
        lambda: ekf().predict([0.1, 0, 0], -np.eye(3)), "R"
    ),
    "EKFSLAM.predict(R 2x2)": lambda f: raises(lambda: ekf().predict([0.1, 0, 0], np.eye(2)), "R"),
    "EKFSLAM.update(z of 3)": lambda f: raises(lambda: ekf().update(1, [1, 0.2, 0.3], _q()), "z"),
    "EKFSLAM.update(Q 3x3)": lambda f: raises(lambda: ekf().update(1, [1, 0.2], np.eye(3)), "Q"),
    "EKFSLAM.update(Q negative)": lambda f: raises(lambda: ekf().update(1, [1, 0.2], -_q()), "Q"),
    "EKFSLAM.update(id a string)": lambda f: raises(
        lambda: ekf().update("tag1", [1, 0.2], _q()), "landmark_id", kind=TypeError
    ),
    "EKFSLAM.update(id 1.5)": lambda f: raises(
        lambda: ekf().update(1.5, [1, 0.2], _q()), "landmark_id", kind=TypeError
    ),
    "EKFSLAM.update(z NaN)": lambda f: raises(lambda: ekf().update(1, [math.nan, 0.2], _q()), "z"),
    "EKFSLAM.update(t NaN)": lambda f: raises(
        lambda: ekf().update(1, [1, 0.2], _q(), t=math.nan), "t"
    ),
    "EKFSLAM.predict_many(lengths differ)": lambda f: raises(
        lambda: ekf().predict_many(np.zeros((2, 3)), np.ones(3), np.ones(2), M=_r3()), "dts"
    ),
    "EKFSLAM.predict_many(negative dts)": lambda f: raises(
        lambda: ekf().predict_many(np.zeros((2, 3)), -np.ones(2), np.ones(2), M=_r3()), "dts"
    ),
    "EKFSLAM.predict_many(NaN us)": lambda f: raises(
        lambda: ekf().predict_many(np.full((2, 3), math.nan), np.ones(2), np.ones(2), M=_r3()),
        "us",
    ),
    "Arena(half_size='1.5')": lambda f: raises(
        lambda: _api().Arena(half_size="1.5", tags=()), "half_size", kind=TypeError
    ),
}


def _with_controls(run, row: int, col: int, value: float):
    values = np.array(run.controls.values, dtype=float)
    values[row, col] = value
    controls = dataclasses.replace(run.controls, values=values)
    return dataclasses.replace(run, controls=controls)


def _our_error(call: Callable[[], object], where: str) -> str | None:
    """Any of our errors (an OutputError is neither a ValueError nor a TypeError) naming `where`."""
    from ekfslam.errors import EkfSlamError

    try:
        call()
    except EkfSlamError as exc:
        return None if where in str(exc) else f"does not name {where}: {exc}"
    except Exception as exc:
        return f"{type(exc).__name__}: {str(exc)[:200]}"
    return "no error"


for _name, _call in API.items():
    add(f"api: {_name}", "api", lambda folder, call=_call: call(folder))


# =============================================================================================
# Family 2: output targets


def _out_case(command: Callable[[Path], list[str]], where: str | Callable[[Path], str], word: str):
    """Run a writing command at a target that cannot be written: refused, nothing written."""

    def check(folder: Path) -> str | None:
        argv = command(folder)
        before = set(folder.rglob("*"))
        r = cli(*argv, cwd=folder)
        named = where(folder) if callable(where) else where
        problem = refused(r, named, word)
        if problem is None:
            new = [str(p) for p in set(folder.rglob("*")) - before]
            if new:
                return f"wrote {new[:3]}"
        return problem

    return check


def _run(folder: Path, *extra: str) -> list[str]:
    return ["run", str(run_folder(folder)), *extra]


LONG = "x" * 300  # over NAME_MAX (255) of every usual file system
LONGISH = "y" * 245  # legal, but a temporary name built from it is not

OUTPUT: dict[str, tuple] = {
    "simulate --out ''": (
        lambda f: ["simulate", "--trajectory", "square", "--out", ""],
        "--out",
        "empty",
    ),
    "tum --out ''": (lambda f: ["tum", str(run_folder(f)), "--out", ""], "--out", "empty"),
    "run --plot ''": (lambda f: _run(f, "--plot", ""), "--plot", "empty"),
    "render-frames --out ''": (
        lambda f: ["render-frames", str(run_folder(f)), "--out", ""],
        "--out",
        "empty",
    ),
    "detect --out ''": (lambda f: ["detect", str(frames_folder(f)), "--out", ""], "--out", "empty"),
    "bench --out ''": (lambda f: ["bench", "--out", "", "--no-mrclam"], "--out", "empty"),
    "run --animate ''": (lambda f: _run(f, "--animate", ""), "--animate", "empty"),
    "run --plot /proc": (
        lambda f: _run(f, "--plot", "/proc/ekfslam-fig.png"),
        "/proc/ekfslam-fig.png",
        "",
    ),
    "run --plot /sys": (
        lambda f: _run(f, "--plot", "/sys/ekfslam-fig.png"),
        "/sys/ekfslam-fig.png",
        "",
    ),
    "simulate --out /proc": (
        lambda f: ["simulate", "--trajectory", "square", "--out", "/proc/ekfslam-run"],
        "/proc/ekfslam-run",
        "",
    ),
    "tum --out /proc": (
        lambda f: ["tum", str(run_folder(f)), "--out", "/proc/ekfslam-tum"],
        "/proc/ekfslam-tum",
        "",
    ),
    "run --animate /proc": (lambda f: _run(f, "--animate", "/proc/a.gif"), "/proc/a.gif", ""),
    "detect --out /proc FILE.csv": (
        lambda f: ["detect", str(frames_folder(f)), "--out", "/proc/d.csv"],
        "/proc/d.csv",
        "",
    ),
    "consistency nees --plot /proc": (
        lambda f: ["consistency", "nees", "--runs", "2", "--plot", "/proc/c.png"],
        "/proc/c.png",
        "",
    ),
    "run --plot name too long": (lambda f: _run(f, "--plot", f"{LONG}.png"), LONG[:40], "long"),
    "simulate --out name too long": (
        lambda f: ["simulate", "--trajectory", "square", "--out", LONG],
        LONG[:40],
        "long",
    ),
    "tum --out name too long": (
        lambda f: ["tum", str(run_folder(f)), "--out", f"d/{LONG}"],
        LONG[:40],
        "long",
    ),
    "run --plot path too long": (
        lambda f: _run(f, "--plot", "/".join(["z" * 200] * 25) + ".png"),
        "z" * 40,
        "long",
    ),
    "run --plot a folder named fig.png": (
        lambda f: (f / "fig.png").mkdir() or _run(f, "--plot", str(f / "fig.png")),
        lambda f: str(f / "fig.png"),
        "folder",
    ),
    "run --plot a link to a folder": (
        lambda f: (
            (f / "d").mkdir()
            or (f / "fig.png").symlink_to(f / "d")
            or _run(f, "--plot", str(f / "fig.png"))
        ),
        lambda f: str(f / "fig.png"),
        "folder",
    ),
    "run --plot under a file": (
        lambda f: (
            (f / "notes.txt").write_text("x")
            and _run(f, "--plot", str(f / "notes.txt" / "fig.png"))
        ),
        lambda f: str(f / "notes.txt"),
        "file",
    ),
    "simulate --out an existing file": (
        lambda f: (
            (f / "taken").write_text("x")
            and ["simulate", "--trajectory", "square", "--out", str(f / "taken")]
        ),
        lambda f: str(f / "taken"),
        "not a folder",
    ),
    "simulate --out under a dangling link": (
        lambda f: (
            (f / "gone").symlink_to(f / "nowhere")
            or ["simulate", "--trajectory", "square", "--out", str(f / "gone" / "run")]
        ),
        lambda f: str(f / "gone"),
        "link",
    ),
    "run --plot under a FIFO": (
        lambda f: os.mkfifo(f / "pipe") or _run(f, "--plot", str(f / "pipe" / "fig.png")),
        lambda f: str(f / "pipe"),
        "",
    ),
}

for _name, (_argv, _where, _word) in OUTPUT.items():
    add(f"output: {_name}", "output", _out_case(_argv, _where, _word or None))


@case("output: run --plot a 245-character name is written", "output")
def _long_but_legal(folder: Path) -> str | None:
    target = folder / f"{LONGISH}.png"
    r = cli(*_run(folder, "--plot", str(target)))
    problem = accepted(r)
    if problem is None and not target.is_file():
        return "no figure written"
    return problem or (f"left {leftovers(folder)}" if leftovers(folder) else None)


@case("output: tum into a 245-character folder name is written", "output")
def _long_folder(folder: Path) -> str | None:
    target = folder / LONGISH[:240]
    r = cli("tum", str(run_folder(folder)), "--out", str(target))
    problem = accepted(r)
    if problem is None and not (target / "trajectory.tum").is_file():
        return "no trajectory.tum written"
    return problem


@case("output: write_run into a read-only-file-system path names it", "output")
def _api_proc(folder: Path) -> str | None:
    return _our_error(
        lambda: _api().write_run(seed_run(), "/sys/ekfslam-corpus"), "/sys/ekfslam-corpus"
    )


@case("output: export_tum onto a folder names it", "output")
def _tum_on_folder(folder: Path) -> str | None:
    from ekfslam.logs.tum import write_tum

    (folder / "t.tum").mkdir()
    return _our_error(lambda: write_tum(folder / "t.tum", np.zeros((1, 8))), str(folder / "t.tum"))


# =============================================================================================
# Family 3: signals


# Writing a temporary file's content is the long part of a write: sleeping after it, with the
# temporary file on disk, holds the command in the middle of its write (text files, figures)
SLOW_RENAME = (
    "import pathlib, time\n_wt = pathlib.Path.write_text\n"
    "def _slow_wt(self, *a, **k):\n    n = _wt(self, *a, **k)\n"
    "    if '.partial' in self.name: time.sleep(60)\n    return n\n"
    "pathlib.Path.write_text = _slow_wt\n"
    "import matplotlib.figure as _mf\n_sf = _mf.Figure.savefig\n"
    "def _slow_sf(self, fname, *a, **k):\n    r = _sf(self, fname, *a, **k)\n"
    "    if '.partial' in str(fname): time.sleep(60)\n    return r\n"
    "_mf.Figure.savefig = _slow_sf\n"
)
BENCH_STUB = SLOW_BENCH = (
    "import benchmarks.cli.bench as b, benchmarks.report as br\n"
    "b.run_benchmarks = lambda config, command: {}\n"
    "br.markdown_table = b.markdown_table = lambda r: 'table'\n"
    "b.plot_costs = lambda r, path: None\n"
)


def _interrupt(
    argv: Callable[[Path], list[str]],
    sig: int,
    pre: str = SLOW_RENAME,
    wait_for: str = ".partial",
    target: Callable[[Path], Path] | None = None,
) -> Check:
    """Start the command, wait until a temporary file appears (or `wait_for` is ""), send `sig`:
    exit 128 + sig, one line, no traceback, no temporary file, the target not half-made."""

    def check(folder: Path) -> str | None:
        args = argv(folder)
        module = _module(args)
        code = [
            "-c",
            f"{pre}\nimport sys, runpy; sys.argv = ['{module}', *sys.argv[1:]]; "
            f"runpy.run_module('{module}', run_name='__main__')",
        ]
        p = subprocess.Popen(
            [sys.executable, *code, *args],
            cwd=folder,
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and p.poll() is None:
            if not wait_for or any(wait_for in q.name for q in folder.rglob("*")):
                break
            time.sleep(0.02)
        else:
            out, err = p.communicate(timeout=60)
            return f"never reached the write (exit {p.returncode}): {_tail(err)}"
        if not wait_for:
            time.sleep(1.5)
        p.send_signal(sig)
        try:
            out, err = p.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            out, err = p.communicate()
            return "did not end within 60 s of the signal"
        problem = interrupted(Ran(p.returncode, out, err), 128 + sig)
        if problem is not None:
            return problem
        left = leftovers(folder)
        if left:
            return f"left {left[:2]}"
        if target is not None and target(folder).exists():
            return f"left a target {target(folder)}"
        return None

    return check


for _sig in (signal.SIGINT, signal.SIGTERM):
    _s = _sig.name
    add(
        f"signal: {_s} in run --plot's write",
        "signal",
        _interrupt(
            lambda f: _run(f, "--plot", str(f / "fig.png")), _sig, target=lambda f: f / "fig.png"
        ),
        "subprocess",
    )
    add(
        f"signal: {_s} in tum's write",
        "signal",
        _interrupt(lambda f: ["tum", str(run_folder(f)), "--out", str(f / "tum")], _sig),
        "subprocess",
    )
    add(
        f"signal: {_s} in simulate's write",
        "signal",
        _interrupt(
            lambda f: [
                "simulate",
                "--trajectory",
                "square",
                "--laps",
                "1",
                "--out",
                str(f / "sim"),
            ],
            _sig,
        ),
        "subprocess",
    )
    add(
        f"signal: {_s} in bench's write",
        "signal",
        _interrupt(
            lambda f: ["bench", "--no-mrclam", "--out", str(f / "bench")],
            _sig,
            SLOW_RENAME + SLOW_BENCH,
        ),
        "subprocess",
    )
    add(
        f"signal: {_s} during a replay",
        "signal",
        _interrupt(
            lambda f: ["run", str(run_folder(f))],
            _sig,
            pre="import ekfslam.pipeline as p, time\n_r = p.replay\n"
            "p.replay = lambda *a, **k: (open('replaying', 'w').close(), time.sleep(60), "
            "_r(*a, **k))[2]\n",
            wait_for="replaying",
        ),
        "subprocess",
    )
add(
    "signal: SIGTERM in render-frames' video",
    "signal",
    _interrupt(
        lambda f: ["render-frames", str(run_folder(f)), "--out", str(f / "frames")],
        signal.SIGTERM,
        pre="import cv2, time\n_W = cv2.VideoWriter\nclass _Slow(_W):\n"
        "    def write(self, image):\n        time.sleep(60)\n        return super().write(image)\n"
        "cv2.VideoWriter = _Slow\n",
        wait_for="frames",
        target=lambda f: f / "frames" / "frames.mp4",
    ),
    "subprocess",
)


# =============================================================================================
# Family 4: plausibility across a file and across files


def _cli_case(
    build: Callable[[Path], tuple[list[str], str]], judge: Callable[[Ran, str], str | None]
):
    def check(folder: Path) -> str | None:
        argv, where = build(folder)
        return judge(cli(*argv, cwd=folder), where)

    return check


def _refuse(word: str) -> Callable[[Ran, str], str | None]:
    return lambda r, where: refused(r, where, word)


def _warn(word: str) -> Callable[[Ran, str], str | None]:
    return lambda r, where: warned(r, where, word)


def _ok(r: Ran, where: str) -> str | None:
    return accepted(r)


def _run_with(edit: Callable[[Path], str]) -> Callable[[Path], tuple[list[str], str]]:
    """A clean run edited by `edit(run folder)`, which returns what the answer must name."""

    def build(folder: Path) -> tuple[list[str], str]:
        run = run_folder(folder)
        return ["run", str(run)], edit(run)

    return build


def _gt_degrees(run: Path) -> str:
    edit_column(run / "groundtruth.csv", "theta", lambda i, v: repr(math.degrees(float(v))))
    return str(run / "groundtruth.csv")


def _hole(moving: bool) -> Callable[[Path], str]:
    """An hour without control rows after row 100 (every file shifted alike)."""

    def edit(run: Path) -> str:
        t_cut = None
        for name in ("controls.csv", "detections.csv", "groundtruth.csv"):
            lines = (run / name).read_text().splitlines()
            if name == "controls.csv":
                t_cut = float(lines[101].split(",")[0])
                if not moving:  # the robot stands still from row 99, the one held over the hole
                    lines = [
                        lines[0],
                        *lines[1:100],
                        *(ln.split(",")[0] + ",0.0,0.0,0.0,0.0" for ln in lines[100:]),
                    ]
            out = [lines[0]]
            for ln in lines[1:]:
                t, rest = ln.split(",", 1)
                out.append(f"{float(t) + 3600.0 if float(t) >= t_cut else float(t)!r},{rest}")
            (run / name).write_text("\n".join(out) + "\n")
        return f"{run / 'controls.csv'}:102"

    return edit


def _tags(points: list[tuple[float, float]] | None) -> Callable[[Path], str]:
    def edit(run: Path) -> str:
        doc = json.loads((run / "run.json").read_text())
        keys = sorted(doc["tag_map"], key=int)
        for k, key in enumerate(keys):
            if points is None:
                doc["tag_map"][key] = [0.5, 0.5]
            elif k < len(points):
                doc["tag_map"][key] = list(points[k])
        (run / "run.json").write_text(json.dumps(doc, indent=2))
        return f"{run / 'run.json'}"

    return edit


def _tag_copied(run: Path) -> str:
    """A tag the run never sees, added to tag_map where tag 0 is (a copy and paste)."""
    doc = json.loads((run / "run.json").read_text())
    doc["tag_map"]["99"] = doc["tag_map"]["0"]
    (run / "run.json").write_text(json.dumps(doc, indent=2))
    return str(run / "run.json")


def _column_value(name: str, column: str, row: int, value: str) -> Callable[[Path], str]:
    def edit(run: Path) -> str:
        edit_column(run / name, column, lambda i, v: value if i == row else v)
        return f"{run / name}:{row + 2}"

    return edit


def _scaled(name: str, columns: tuple[str, ...], factor: float) -> Callable[[Path], str]:
    def edit(run: Path) -> str:
        for column in columns:
            edit_column(run / name, column, lambda i, v: repr(float(v) * factor))
        return str(run / name)

    return edit


def _other_run_mixed(run: Path) -> str:
    """The detections of a run of another trajectory merged into this run's, in time order."""
    from ekfslam import SimulationConfig, simulate

    other = simulate(SimulationConfig(trajectory="octagon", laps=1, seed=9)).detections
    lines = (run / "detections.csv").read_text().splitlines()
    extra = [
        f"{t!r},{i},{r!r},{b!r}"
        for t, i, r, b in zip(
            other.t.tolist(),
            other.tag_id.tolist(),
            other.range.tolist(),
            other.bearing.tolist(),
            strict=True,
        )
        if t <= float(lines[-1].split(",")[0])
    ]
    rows = sorted(lines[1:] + extra, key=lambda ln: float(ln.split(",")[0]))
    (run / "detections.csv").write_text("\n".join([lines[0], *rows]) + "\n")
    return str(run / "detections.csv")


def _no_truth(folder: Path) -> tuple[list[str], str]:
    run = run_folder(folder)
    (run / "groundtruth.csv").unlink()
    return ["render-frames", str(run), "--out", str(folder / "frames")], str(run)


PLAUSIBILITY = {
    "ground-truth heading in degrees": (_run_with(_gt_degrees), _refuse("degrees")),
    "an hour without controls while moving": (_run_with(_hole(True)), _refuse("3600")),
    "an hour without controls at rest": (_run_with(_hole(False)), lambda r, w: accepted(r)),
    "every tag at one point": (_run_with(_tags(None)), _refuse("one point")),
    "two tags at one point": (_run_with(_tag_copied), _warn("same point")),
    "a wheel speed of 1e300": (
        _run_with(_column_value("controls.csv", "w1", 40, "1e300")),
        _refuse("w1"),
    ),
    "a range of 1e300": (
        _run_with(_column_value("detections.csv", "range", 5, "1e300")),
        _refuse("range"),
    ),
    "a time of 1e300": (
        _run_with(_column_value("controls.csv", "t", 40, "1e300")),
        _refuse("time"),
    ),
    "a ground-truth x of 1e300": (
        _run_with(_column_value("groundtruth.csv", "x", 3, "1e300")),
        _refuse("x"),
    ),
    "ranges in millimetres": (
        _run_with(_scaled("detections.csv", ("range",), 1000.0)),
        _refuse("range"),
    ),
    "ground truth in millimetres": (
        _run_with(_scaled("groundtruth.csv", ("x", "y"), 1000.0)),
        _refuse("groundtruth"),
    ),
    "render-frames without ground truth": (_no_truth, _refuse("ground truth")),
    "another run's detections merged in": (_run_with(_other_run_mixed), _refuse("fit")),
    "simulate a start outside the arena": (
        lambda f: (
            [
                "simulate",
                "--trajectory",
                "square",
                "--start-error",
                "-0.5",
                "-0.5",
                "0",
                "--out",
                str(f / "sim"),
            ],
            "--start-error",
        ),
        _refuse("arena"),
    ),
}
for _name, (_build, _judge) in PLAUSIBILITY.items():
    add(f"plausibility: {_name}", "plausibility", _cli_case(_build, _judge))


@case("plausibility: simulate(start outside the arena) in the API", "plausibility")
def _sim_outside(folder: Path) -> str | None:
    api = _api()
    return raises(lambda: api.simulate(api.SimulationConfig(start_error=(-1.0, 0.0, 0.0))), "arena")


def _mrclam_case(
    defect: Callable[[Path, Path], str],
    judge: Callable[[Ran, str], str | None],
    command: str = "run",
):
    def check(folder: Path) -> str | None:
        ds = mrclam_folder(folder)
        where = defect(ds, folder)
        if command == "run":
            argv = ["run", str(ds), "--robot", "1"]
        else:
            argv = ["convert", "mrclam", str(ds), "--robot", "1", "--out", str(folder / "out")]
        return judge(cli(*argv, cwd=folder), where)

    return check


def _robot2_mixed(ds: Path, folder: Path) -> str:
    path = ds / "Robot1_Measurement.dat"
    lines = dat_rows(path)
    while lines and not lines[-1]:
        lines.pop()
    n = len(lines)
    extra = [ln for ln in dat_rows(folder / "robot2-measurements.dat") if ln]
    path.write_bytes(b"\r\n".join(lines + extra) + b"\r\n")
    return f"{path}:{n + 1}"


def _robot2_merged(ds: Path, folder: Path) -> str:
    """Robot 2's measurements merged into robot 1's in time order: no step back in time."""
    path = ds / "Robot1_Measurement.dat"
    lines = [ln for ln in dat_rows(path) if ln]
    head = [ln for ln in lines if ln.startswith(b"#")]
    rows = [ln for ln in lines if not ln.startswith(b"#")]
    rows += [ln for ln in dat_rows(folder / "robot2-measurements.dat") if ln]
    rows.sort(key=lambda ln: float(ln.split()[0]))
    path.write_bytes(b"\r\n".join(head + rows) + b"\r\n")
    return str(path)


def _odometry_back(seconds: float) -> Callable[[Path, Path], str]:
    def defect(ds: Path, folder: Path) -> str:
        path = ds / "Robot1_Odometry.dat"
        lines = dat_rows(path)
        i = data_index(lines, 200)
        t, rest = lines[i].split(None, 1)
        lines[i] = b"%r " % (float(t) - seconds) + rest
        path.write_bytes(b"\r\n".join(lines))
        return f"{path}:{i + 1}"

    return defect


def _odometry_hole(ds: Path, folder: Path) -> str:
    path = ds / "Robot1_Odometry.dat"
    lines = dat_rows(path)
    i = data_index(lines, 200)
    for j in range(i, len(lines)):
        if lines[j] and not lines[j].startswith(b"#"):
            t, rest = lines[j].split(None, 1)
            lines[j] = b"%r " % (float(t) + 3600.0) + rest
    for name in ("Robot1_Measurement.dat", "Robot1_Groundtruth.dat"):
        other = ds / name
        t_cut = float(lines[i].split()[0]) - 3600.0
        out = []
        for ln in dat_rows(other):
            if ln and not ln.startswith(b"#") and float(ln.split()[0]) >= t_cut:
                t, rest = ln.split(None, 1)
                ln = b"%r " % (float(t) + 3600.0) + rest
            out.append(ln)
        other.write_bytes(b"\r\n".join(out))
    path.write_bytes(b"\r\n".join(lines))
    return f"{path}:{i + 1}"


def _mrclam_value(name: str, k: int, column: int, value: bytes) -> Callable[[Path, Path], str]:
    def defect(ds: Path, folder: Path) -> str:
        path = ds / name
        lines = dat_rows(path)
        i = data_index(lines, k)
        cells = lines[i].split()
        cells[column] = value
        lines[i] = b" ".join(cells)
        path.write_bytes(b"\r\n".join(lines))
        return f"{path}:{i + 1}"

    return defect


def _mrclam_gt_degrees(ds: Path, folder: Path) -> str:
    path = ds / "Robot1_Groundtruth.dat"
    out = []
    for ln in dat_rows(path):
        if ln and not ln.startswith(b"#"):
            cells = ln.split()
            cells[3] = repr(math.degrees(float(cells[3]))).encode()
            ln = b" ".join(cells)
        out.append(ln)
    path.write_bytes(b"\r\n".join(out))
    return str(path)


MRCLAM_PLAUSIBILITY = {
    "MRCLAM: another robot's measurements appended": (_robot2_mixed, _refuse("back")),
    "MRCLAM: another robot's measurements merged in time order": (_robot2_merged, _refuse("fit")),
    "MRCLAM: odometry jumps back an hour": (_odometry_back(3600.0), _refuse("back")),
    "MRCLAM: odometry goes back 5 s": (_odometry_back(5.0), _refuse("back")),
    "MRCLAM: two odometry rows 20 ms out of order": (_odometry_back(0.02), _warn("order")),
    "MRCLAM: an hour without odometry while moving": (_odometry_hole, _refuse("3600")),
    "MRCLAM: ground-truth heading in degrees": (_mrclam_gt_degrees, _refuse("degrees")),
    "MRCLAM: odometry v of 1e300": (
        _mrclam_value("Robot1_Odometry.dat", 50, 1, b"1e300"),
        _refuse("v"),
    ),
    "MRCLAM: a range of 1e300": (
        _mrclam_value("Robot1_Measurement.dat", 3, 2, b"1e300"),
        _refuse("range"),
    ),
}
for _name, (_defect, _judge) in MRCLAM_PLAUSIBILITY.items():
    add(f"plausibility: {_name}", "plausibility", _mrclam_case(_defect, _judge), "mrclam")
add(
    "plausibility: convert mrclam, odometry jumps back an hour",
    "plausibility",
    _mrclam_case(_odometry_back(3600.0), _refuse("back"), "convert"),
    "mrclam",
)


# =============================================================================================
# Family 5: files, one defect each (encodings, line ends, digits, special files)


def _file_case(
    name: str, corrupt: Callable[[Path], None], judge: str, word: str = "", line: bool = False
) -> Check:
    """A clean run with `name` corrupted; judge: "refuse" (naming the file), "same" (results as
    the clean run's)."""

    def check(folder: Path) -> str | None:
        run = run_folder(folder)
        corrupt(run / name)
        r = cli("run", str(run), cwd=folder, timeout=120)
        if judge == "same":
            clean = _clean_output()
            return same_output(r, clean)
        return refused(r, str(run / name) + (":" if line else ""), word or None)

    return check


def _clean_output() -> Ran:
    if "clean" not in _STATE:
        _STATE["clean"] = cli("run", str(clean_run()))
    return _STATE["clean"]  # type: ignore[return-value]


def _bytes(edit: Callable[[bytes], bytes]) -> Callable[[Path], None]:
    return lambda p: p.write_bytes(edit(p.read_bytes()))


def _replace_with(make: Callable[[Path], None]) -> Callable[[Path], None]:
    def corrupt(p: Path) -> None:
        p.unlink()
        make(p)

    return corrupt


def _cell(column: str, row: int, value: str) -> Callable[[Path], None]:
    return lambda p: edit_column(p, column, lambda i, v: value if i == row else v)


def _insert_line(index: int, text: str) -> Callable[[Path], None]:
    return lambda p: edit_lines(p, lambda ls: [*ls[:index], text, *ls[index:]])


CSV_DEFECTS: dict[str, tuple[Callable[[Path], None], str, str, bool]] = {
    "a UTF-8 BOM": (_bytes(lambda b: b"\xef\xbb\xbf" + b), "same", "", False),
    "CRLF line ends": (_bytes(lambda b: b.replace(b"\n", b"\r\n")), "same", "", False),
    "spaces around the cells": (_bytes(lambda b: b.replace(b",", b" , ")), "same", "", False),
    "-0.0 for 0.0": (_bytes(lambda b: b.replace(b",0.0\n", b",-0.0\n")), "same", "", False),
    "blank lines at the end": (_bytes(lambda b: b + b"\n\n\n"), "same", "", False),
    "UTF-16": (_bytes(lambda b: b.decode().encode("utf-16")), "refuse", "UTF-8", False),
    "a Latin-1 byte": (_bytes(lambda b: b.replace(b"\n", b"\xe9\n", 3)), "refuse", "UTF-8", True),
    "a NUL byte": (_bytes(lambda b: b[:40] + b"\0" + b[40:]), "refuse", "", True),
    "the header repeated inside": (
        lambda p: edit_lines(p, lambda ls: [*ls[:20], ls[0], *ls[20:]]),
        "refuse",
        "header",
        True,
    ),
    "an extra column": (
        lambda p: edit_lines(p, lambda ls: [ln + ",0" for ln in ls]),
        "refuse",
        "column",
        True,
    ),
    "a column missing": (
        lambda p: edit_lines(p, lambda ls: [ln.rsplit(",", 1)[0] for ln in ls]),
        "refuse",
        "column",
        True,
    ),
    "duplicate column names": (
        lambda p: edit_lines(p, lambda ls: [ls[0].replace(ls[0].split(",")[1], "t", 1), *ls[1:]]),
        "refuse",
        "",
        True,
    ),
    "Arabic-Indic digits": (_cell("t", 10, "\u0661\u0662"), "refuse", "", True),
    "fullwidth digits": (_cell("t", 10, "\uff11\uff12"), "refuse", "", True),
    "a quoted number": (_cell("t", 10, '"1.5"'), "refuse", "", True),
    "a decimal comma": (_bytes(lambda b: b.replace(b".", b",", 5)), "refuse", "", True),
    "semicolons": (_bytes(lambda b: b.replace(b",", b";")), "refuse", "header", True),
    "tabs": (_bytes(lambda b: b.replace(b",", b"\t")), "refuse", "header", True),
    "a truncated last line": (
        _bytes(lambda b: b.rstrip(b"\n").rsplit(b",", 1)[0] + b"\n"),
        "refuse",
        "fields",
        True,
    ),
    "a blank line inside": (_insert_line(15, ""), "refuse", "blank", True),
    "NaN": (_cell("t", 10, "nan"), "refuse", "finite", True),
    "inf": (_cell("t", 10, "inf"), "refuse", "finite", True),
    "hex": (_cell("t", 10, "0x10"), "refuse", "number", True),
    "an underscore in a number": (_cell("t", 10, "1_000"), "refuse", "number", True),
    "an empty file": (lambda p: p.write_bytes(b""), "refuse", "empty", True),
    "the header alone": (lambda p: edit_lines(p, lambda ls: ls[:1]), "refuse", "", True),
    "a 20 MB line": (
        _bytes(lambda b: b.rstrip(b"\n") + b"," + b"9" * 20_000_000 + b"\n"),
        "refuse",
        "",
        True,
    ),
    "a folder": (_replace_with(lambda p: p.mkdir()), "refuse", "folder", False),
    "a symbolic link to /dev/null": (
        _replace_with(lambda p: p.symlink_to("/dev/null")),
        "refuse",
        "device",
        False,
    ),
    "a FIFO": (_replace_with(lambda p: os.mkfifo(p)), "refuse", "FIFO", False),
    "a dangling symbolic link": (
        _replace_with(lambda p: p.symlink_to(p.parent / "gone")),
        "refuse",
        "dangling",
        False,
    ),
}
for _file in ("controls.csv", "detections.csv", "groundtruth.csv"):
    for _name, (_corrupt, _judge, _word, _line) in CSV_DEFECTS.items():
        if _file != "controls.csv" and _name in (
            "Arabic-Indic digits",
            "hex",
            "NaN",
            "a quoted number",
            "the header alone",
            "semicolons",
            "a decimal comma",
            "duplicate column names",
        ):
            continue  # once is enough for the cell rules, which one reader shares
        add(f"file: {_file}, {_name}", "file", _file_case(_file, _corrupt, _judge, _word, _line))
add(
    "file: detections.csv, tag_id 3.0",
    "file",
    _file_case("detections.csv", _cell("tag_id", 4, "3.0"), "refuse", "integer", True),
)
add(
    "file: detections.csv, tag_id beyond int64",
    "file",
    _file_case("detections.csv", _cell("tag_id", 4, str(2**70)), "refuse", "", True),
)
add(
    "file: detections.csv, tag_ids written +3",
    "file",
    _file_case(
        "detections.csv",
        lambda p: edit_column(p, "tag_id", lambda i, v: "+" + v),
        "same",
    ),
)
add(
    "file: groundtruth.csv, the header alone",
    "file",
    _file_case("groundtruth.csv", lambda p: edit_lines(p, lambda ls: ls[:1]), "refuse", "", True),
)


def _json_edit(edit: Callable[[dict], None]) -> Callable[[Path], None]:
    def corrupt(p: Path) -> None:
        doc = json.loads(p.read_text())
        edit(doc)
        p.write_text(json.dumps(doc, indent=2))

    return corrupt


def _json_text(edit: Callable[[str], str]) -> Callable[[Path], None]:
    return lambda p: p.write_text(edit(p.read_text()))


def _set(key: str, value: object) -> Callable[[dict], None]:
    return lambda d: d.__setitem__(key, value)


RUN_JSON: dict[str, tuple[Callable[[Path], None], str, str]] = {
    "a UTF-8 BOM": (_bytes(lambda b: b"\xef\xbb\xbf" + b), "same", ""),
    "CRLF line ends": (_bytes(lambda b: b.replace(b"\n", b"\r\n")), "same", ""),
    "UTF-16": (_bytes(lambda b: b.decode().encode("utf-16")), "refuse", "UTF-8"),
    "a duplicate key": (
        _json_text(lambda t: t.replace('"name":', '"name": "a",\n  "name":', 1)),
        "refuse",
        "twice",
    ),
    "a trailing comma": (
        _json_text(lambda t: t.rstrip().rstrip("}").rstrip() + ",\n}\n"),
        "refuse",
        "",
    ),
    "a comment": (_json_text(lambda t: "// my run\n" + t), "refuse", ""),
    "NaN in nominal_start": (
        _json_text(
            lambda t: re.sub(r'"nominal_start": \[[^\]]*\]', '"nominal_start": [NaN, 0.0, 0.0]', t)
        ),
        "refuse",
        "NaN",
    ),
    "format_version '1'": (_json_edit(_set("format_version", "1")), "refuse", "format_version"),
    "format_version 1.0": (_json_edit(_set("format_version", 1.0)), "refuse", "format_version"),
    "nominal_start as strings": (
        _json_edit(_set("nominal_start", ["0", "0", "0"])),
        "refuse",
        "nominal_start",
    ),
    "nominal_start of 2": (
        _json_edit(_set("nominal_start", [0.0, 0.0])),
        "refuse",
        "nominal_start",
    ),
    "nominal_start a kilometre from the map": (
        _json_edit(_set("nominal_start", [1000.0, 0.0, 0.0])),
        "refuse",
        "nominal_start",
    ),
    "a tag at 3 coordinates": (
        _json_edit(lambda d: d["tag_map"].__setitem__("0", [0.1, 0.2, 0.3])),
        "refuse",
        "tag_map",
    ),
    "a tag id 1.0": (
        _json_edit(lambda d: d["tag_map"].__setitem__("1.0", d["tag_map"].pop("1"))),
        "refuse",
        "integer",
    ),
    "a tag id in Arabic-Indic digits": (
        _json_edit(lambda d: d["tag_map"].__setitem__("\u0661\u0663", d["tag_map"].pop("1"))),
        "refuse",
        "",
    ),
    "wheel_radius '0.03'": (
        _json_edit(lambda d: d["robot"].__setitem__("wheel_radius", "0.03")),
        "refuse",
        "wheel_radius",
    ),
    "units in degrees": (
        _json_edit(lambda d: d["units"].__setitem__("angle", "deg")),
        "refuse",
        "units",
    ),
    "an unknown key": (_json_edit(_set("notes", "hello")), "refuse", "unknown key"),
    "controls_hz -20": (
        _json_edit(lambda d: d["rates"].__setitem__("controls_hz", -20)),
        "refuse",
        "controls_hz",
    ),
    "camera_mounting without yaw": (
        _json_edit(lambda d: d["camera_mounting"].pop("yaw")),
        "refuse",
        "camera_mounting",
    ),
    "a JSON array": (_json_text(lambda t: "[" + t + "]"), "refuse", ""),
    "empty": (lambda p: p.write_text(""), "refuse", ""),
    "a symbolic link to /dev/null": (
        _replace_with(lambda p: p.symlink_to("/dev/null")),
        "refuse",
        "device",
    ),
    "a FIFO": (_replace_with(lambda p: os.mkfifo(p)), "refuse", "FIFO"),
    "20 MB of spaces": (
        _json_text(lambda t: t.replace("{", "{" + " " * 20_000_000, 1)),
        "same",
        "",
    ),
}
for _name, (_corrupt, _judge, _word) in RUN_JSON.items():
    add(f"file: run.json, {_name}", "file", _file_case("run.json", _corrupt, _judge, _word))


@case("file: a run folder that is a file", "file")
def _run_is_file(folder: Path) -> str | None:
    (folder / "run").write_text("x")
    return refused(cli("run", str(folder / "run")), str(folder / "run"), "folder")


@case("file: a run folder given with a trailing slash", "file")
def _trailing_slash(folder: Path) -> str | None:
    return same_output(cli("run", str(run_folder(folder)) + "/"), _clean_output())


@case("file: a run folder through a symbolic link", "file")
def _run_link(folder: Path) -> str | None:
    (folder / "link").symlink_to(run_folder(folder))
    return same_output(cli("run", str(folder / "link")), _clean_output())


def _mrclam_file(defect: Callable[[Path], str], judge: Callable[[Ran, str], str | None]) -> Check:
    return _mrclam_case(lambda ds, folder: defect(ds), judge)


def _mrclam_bytes(name: str, edit: Callable[[bytes], bytes]) -> Callable[[Path], str]:
    def defect(ds: Path) -> str:
        (ds / name).write_bytes(edit((ds / name).read_bytes()))
        return str(ds / name)

    return defect


def _mrclam_special(name: str, make: Callable[[Path], None]) -> Callable[[Path], str]:
    def defect(ds: Path) -> str:
        (ds / name).unlink()
        make(ds / name)
        return str(ds / name)

    return defect


def _mrclam_same(defect: Callable[[Path], str]) -> Check:
    def check(folder: Path) -> str | None:
        clean_ds = mrclam_folder(folder / "clean")
        clean = cli("run", str(clean_ds), "--robot", "1")
        ds = mrclam_folder(folder)
        defect(ds)
        return same_output(cli("run", str(ds), "--robot", "1"), clean)

    return check


MRCLAM_FILES = {
    "Odometry in UTF-16": (
        _mrclam_bytes("Robot1_Odometry.dat", lambda b: b.decode().encode("utf-16")),
        _refuse(""),
    ),
    "Odometry with an extra column": (
        _mrclam_bytes("Robot1_Odometry.dat", lambda b: b.replace(b"\r\n1", b" 0\r\n1", 3)),
        _refuse("columns"),
    ),
    "Odometry headers only": (
        _mrclam_bytes(
            "Robot1_Odometry.dat",
            lambda b: b"\r\n".join(ln for ln in b.split(b"\r\n") if ln.startswith(b"#")) + b"\r\n",
        ),
        _refuse("empty"),
    ),
    "Barcodes.dat a FIFO": (_mrclam_special("Barcodes.dat", os.mkfifo), _refuse("FIFO")),
    "Barcodes.dat a link to /dev/null": (
        _mrclam_special("Barcodes.dat", lambda p: p.symlink_to("/dev/null")),
        _refuse("device"),
    ),
    "Robot1_Odometry.dat a FIFO": (
        _mrclam_special("Robot1_Odometry.dat", os.mkfifo),
        _refuse("FIFO"),
    ),
    "Robot1_Measurement.dat a link to /dev/null": (
        _mrclam_special("Robot1_Measurement.dat", lambda p: p.symlink_to("/dev/null")),
        _refuse("device"),
    ),
    "Landmark_Groundtruth.dat a folder": (
        _mrclam_special("Landmark_Groundtruth.dat", lambda p: p.mkdir()),
        _refuse("folder"),
    ),
    "Robot1_Groundtruth.dat a FIFO": (
        _mrclam_special("Robot1_Groundtruth.dat", os.mkfifo),
        _refuse("FIFO"),
    ),
    "Measurement with a NUL byte": (
        _mrclam_bytes("Robot1_Measurement.dat", lambda b: b[:300] + b"\0" + b[300:]),
        _refuse(""),
    ),
}
for _name, (_defect, _judge) in MRCLAM_FILES.items():
    add(f"file: MRCLAM {_name}", "file", _mrclam_file(_defect, _judge), "mrclam")
add(
    "file: MRCLAM Measurement bearing in Arabic-Indic digits",
    "file",
    _mrclam_case(
        _mrclam_value("Robot1_Measurement.dat", 2, 3, "\u0660.\u0661".encode()), _refuse("bearing")
    ),
    "mrclam",
)
add(
    "file: MRCLAM Odometry with a BOM",
    "file",
    _mrclam_same(_mrclam_bytes("Robot1_Odometry.dat", lambda b: b"\xef\xbb\xbf" + b)),
    "mrclam",
)
add(
    "file: MRCLAM files with LF line ends",
    "file",
    _mrclam_same(
        lambda ds: (
            [p.write_bytes(p.read_bytes().replace(b"\r\n", b"\n")) for p in ds.glob("*.dat")]
            and str(ds)
        )
    ),
    "mrclam",
)


def _frames_case(defect: Callable[[Path], str], word: str) -> Check:
    """A frames run with one defect; the refusal names the defect's file, or the run's folder
    where the fault shows in another of its files (frames.csv's frame, the video's end)."""

    def check(folder: Path) -> str | None:
        run = frames_folder(folder)
        defect(run)
        return refused(cli("run", str(run), cwd=folder), str(run), word or None)

    return check


def _frames_csv(edit: Callable[[list[str]], list[str]]) -> Callable[[Path], str]:
    def defect(run: Path) -> str:
        edit_lines(run / "frames.csv", edit)
        return str(run / "frames.csv")

    return defect


FRAMES = {
    "frames.csv missing": (lambda r: (r / "frames.csv").unlink() or str(r / "frames.csv"), ""),
    "frames.csv a FIFO": (
        lambda r: (
            (r / "frames.csv").unlink() or os.mkfifo(r / "frames.csv") or str(r / "frames.csv")
        ),
        "FIFO",
    ),
    "frames.csv times in nanoseconds": (
        _frames_csv(
            lambda ls: [
                ls[0],
                *(f"{float(x.split(',')[0]) * 1e9!r},{x.split(',')[1]}" for x in ls[1:]),
            ]
        ),
        "",
    ),
    "frames.csv frame beyond the video": (
        _frames_csv(lambda ls: [*ls, f"{float(ls[-1].split(',')[0]) + 0.1!r},99999"]),
        "video",
    ),
    "frames.csv frames out of order": (_frames_csv(lambda ls: [ls[0], ls[2], ls[1], *ls[3:]]), ""),
    "the video a folder": (
        lambda r: (
            (r / "frames.mp4").unlink() or (r / "frames.mp4").mkdir() or str(r / "frames.mp4")
        ),
        "",
    ),
    "the video empty": (lambda r: (r / "frames.mp4").write_bytes(b"") or str(r / "frames.mp4"), ""),
}
for _name, (_defect, _word) in FRAMES.items():
    add(f"file: frames run, {_name}", "file", _frames_case(_defect, _word))


def _bag_case(defect: Callable[[Path], Path], word: str) -> Check:
    def check(folder: Path) -> str | None:
        bag = rosbag_folder(folder)
        where = defect(bag)
        r = cli(
            "convert", "rosbag", str(where), *ROSBAG_ARGS, "--out", str(folder / "out"), cwd=folder
        )
        return refused(r, str(where), word or None)

    return check


def _bag_db(bag: Path) -> Path:
    return next(p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))


BAGS = {
    "an empty .bag file": (
        lambda b: (b.parent / "empty.bag").write_bytes(b"") or b.parent / "empty.bag",
        "",
    ),
    "a truncated database": (
        lambda b: _bag_db(b).write_bytes(_bag_db(b).read_bytes()[:3000]) or b,
        "",
    ),
    "metadata.yaml garbage": (lambda b: (b / "metadata.yaml").write_text("{{{: not yaml") or b, ""),
    "metadata.yaml a FIFO": (
        lambda b: (b / "metadata.yaml").unlink() or os.mkfifo(b / "metadata.yaml") or b,
        "",
    ),
    "the database missing": (lambda b: _bag_db(b).unlink() or b, ""),
}
for _name, (_defect, _word) in BAGS.items():
    add(f"file: ROS bag, {_name}", "file", _bag_case(_defect, _word))


@case("file: ROS bag, clean, converts", "file")
def _bag_clean(folder: Path) -> str | None:
    bag = rosbag_folder(folder)
    return accepted(cli("convert", "rosbag", str(bag), *ROSBAG_ARGS, "--out", str(folder / "out")))


# =============================================================================================
# Family 6: options that contradict each other


OPTIONS = {
    "bench --mrclam 7 --no-mrclam": (["bench", "--mrclam", "7", "--no-mrclam"], "--no-mrclam"),
    "bench --no-mrclam --mrclam 7": (["bench", "--no-mrclam", "--mrclam", "7"], "--mrclam"),
    "bench --no-mr --mrclam 7 (abbreviated)": (["bench", "--no-mr", "--mrclam", "7"], "--mrclam"),
    "run --robot 1 --robot 2": (["run", str(SEED_RUN), "--robot", "1", "--robot", "2"], "--robot"),
    "run --plot a.png --plot b.png": (
        ["run", str(SEED_RUN), "--plot", "a.png", "--plot", "b.png"],
        "--plot",
    ),
    "run --sigma-range twice": (
        ["run", str(SEED_RUN), "--sigma-range", "0.1", "--sigma-range", "0.2"],
        "--sigma-range",
    ),
    "run --start twice": (
        ["run", str(SEED_RUN), "--start", "0", "0", "0", "--start", "1", "1", "1"],
        "--start",
    ),
    "simulate --trajectory twice": (
        ["simulate", "--trajectory", "square", "--trajectory", "octagon", "--out", "x"],
        "--trajectory",
    ),
    "run --linearization twice": (
        ["run", str(SEED_RUN), "--linearization", "fej", "--linearization", "invariant"],
        "--linearization",
    ),
}
for _name, (_argv, _opt) in OPTIONS.items():
    add(
        f"option: {_name}",
        "option",
        lambda folder, a=_argv, o=_opt: refused(cli(*a, cwd=folder), o),
    )


@case("option: run --json --json is harmless", "option")
def _json_twice(folder: Path) -> str | None:
    return accepted(cli("run", str(SEED_RUN), "--json", "--json"))


@case("option: run --robot 1 --robot 1 is harmless", "option")
def _same_twice(folder: Path) -> str | None:
    r = cli("run", str(SEED_RUN), "--robot", "1", "--robot", "1")
    return refused(r, str(SEED_RUN), "--robot")  # --robot is for MRCLAM only: refused for that


# =============================================================================================
# Scoring


def run_case(name: str, root: Path) -> str | None:
    """Run one case in a fresh folder under `root`; None if right, else why not."""
    c = CASES[name]
    folder = root / f"case-{abs(hash(name)) % 10**8:08d}"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    try:
        return c.check(folder)
    except Exception as exc:  # building the input failed, or ekfslam raised in-process
        return f"{type(exc).__name__} while checking: {str(exc)[:300]}"
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def available(c: Case) -> str | None:
    """Why a case cannot run here (Dataset 7 missing), or None."""
    if c.needs == "mrclam":
        try:
            from ekfslam.logs.mrclam.load import find_dataset

            find_dataset(7)
        except Exception:
            return "needs MRCLAM Dataset 7"
    return None


def _isolated(name: str, root: Path, timeout: float) -> str | None:
    """`run_case` in its own process (a case that hangs or kills its process is wrong)."""
    try:
        p = subprocess.run(
            [sys.executable, __file__, "--case", name, "--root", str(root)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return f"did not end within {timeout:g} s"
    last = _lines(p.stdout)[-1:] or ["WRONG: no verdict: " + _tail(p.stderr)]
    return None if last[0] == "RIGHT" else last[0].removeprefix("WRONG: ")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", default="", help="run the cases whose name holds this")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=300)
    parser.add_argument("--list", action="store_true")
    parser.add_argument("--case", help=argparse.SUPPRESS)
    parser.add_argument("--root", type=Path, default=Path("/tmp/ekfslam-corpus"))
    parser.add_argument("--json", type=Path, help="write each case's verdict here")
    args = parser.parse_args()
    if args.case:
        verdict = run_case(args.case, args.root)
        print("RIGHT" if verdict is None else f"WRONG: {' '.join(verdict.split())}")
        return 0
    names = [n for n in CASES if args.only in n]
    if args.list:
        print("\n".join(f"{CASES[n].family:13s} {n}" for n in names))
        return 0
    skipped = {n: why for n in names if (why := available(CASES[n])) is not None}
    todo = [n for n in names if n not in skipped]
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        verdicts = dict(
            zip(todo, pool.map(lambda n: _isolated(n, args.root, args.timeout), todo), strict=True)
        )
    by_family: dict[str, list[int]] = {f: [0, 0] for f in FAMILIES}
    for name, verdict in verdicts.items():
        tally = by_family[CASES[name].family]
        tally[0] += verdict is None
        tally[1] += 1
        if verdict is not None:
            print(f"WRONG {name}: {verdict}")
    right = sum(t[0] for t in by_family.values())
    print()
    for family, (ok, n) in by_family.items():
        print(f"{family:13s} right {ok} of {n}")
    print(
        f"{'all':13s} right {right} of {len(verdicts)}"
        + (f" ({len(skipped)} skipped: {sorted(set(skipped.values()))})" if skipped else "")
    )
    if args.json:
        args.json.write_text(json.dumps(verdicts, indent=1))
    return 0


if __name__ == "__main__":
    with contextlib.suppress(KeyboardInterrupt):
        sys.exit(main())
