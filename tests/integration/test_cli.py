"""The command line, as a user runs it: subprocesses, exit codes, one-line errors."""

from __future__ import annotations

import dataclasses
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from ekfslam_cli import run_ekfslam

from ekfslam import read_run
from ekfslam.core.filter.backend import COMPILER, ROOTS, models_of
from ekfslam.core.models import ODOMETRY, RANGE_BEARING

REPO = Path(__file__).resolve().parents[2]
RUNS = REPO / "data" / "runs"


cli = run_ekfslam


@pytest.mark.slow
@pytest.mark.parametrize("name", ["square-2laps", "octagon-2laps"])
def test_run_json_recovers_the_true_start(name: str, tmp_path: Path):
    plot = tmp_path / f"{name}.png"
    out = cli("run", str(RUNS / name), "--json", "--plot", str(plot))
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    a = d["alignment"]
    for key in ("x0", "y0", "theta0", "start_pose", "mean_error", "rmse"):
        assert key in a
    assert d["landmarks"]["count"] == 8
    assert d["updates"]["accepted"] > 300
    assert d["updates"]["rejected"] >= 0
    assert d["seconds"] > 0
    # the acceptance figure: the true start within 3 cm and 0.03 rad
    truth = read_run(RUNS / name).groundtruth.pose[0]
    start = np.array(a["start_pose"])
    assert np.hypot(*(start[:2] - truth[:2])) < 0.03
    assert abs(start[2] - truth[2]) < 0.03
    assert d["true_start"] == pytest.approx(truth.tolist())
    # eq. (17)'s convention: world = R(θ0) estimate + (x0, y0), applied to the nominal start
    c, s = np.cos(a["theta0"]), np.sin(a["theta0"])
    nominal = np.array([-0.375, -0.375])
    expected = np.array([c * nominal[0] - s * nominal[1], s * nominal[0] + c * nominal[1]])
    np.testing.assert_allclose(start[:2], expected + np.array([a["x0"], a["y0"]]), atol=1e-12)
    assert d["trajectory"]["ate_rmse"] is not None
    assert plot.stat().st_size > 20_000  # a real PNG with content


def test_run_prints_the_table_row_next_to_the_seeds():
    out = cli("run", str(RUNS / "square-2laps"))
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].split() == ["Trajectory", "x0", "y0", "theta0", "Average", "Error"]
    row = lines[1].split()
    assert row[0] == "square-2laps" and len(row) == 5
    assert [float(v) for v in row[1:]]  # four numbers
    assert "-0.020" in lines[2] and "0.153" in lines[2]  # the seed's own Table 1 row
    assert any("updates accepted" in line for line in lines)


@pytest.mark.slow
def test_noise_and_init_options_change_the_result():
    base = json.loads(cli("run", str(RUNS / "octagon-2laps"), "--json").stdout)
    seed = json.loads(cli("run", str(RUNS / "octagon-2laps"), "--json", "--init", "seed").stdout)
    tight = json.loads(
        cli("run", str(RUNS / "octagon-2laps"), "--json", "--sigma-range", "0.002").stdout
    )
    assert base["alignment"]["mean_error"] != seed["alignment"]["mean_error"]
    # far too small a Q: the gate throws away good observations
    assert tight["updates"]["rejected"] > base["updates"]["rejected"]
    off = json.loads(
        cli(
            "run", str(RUNS / "octagon-2laps"), "--json", "--sigma-range", "0.002", "--gate", "0"
        ).stdout
    )
    assert off["updates"]["rejected"] == 0


def test_run_takes_each_linearization():
    out = {
        lin: json.loads(
            cli("run", str(RUNS / "octagon-2laps"), "--json", "--linearization", lin).stdout
        )
        for lin in ("standard", "invariant")
    }
    # the same sightings, another filter: every one used, a different estimate
    assert out["standard"]["updates"] == out["invariant"]["updates"]
    assert out["standard"]["alignment"] != out["invariant"]["alignment"]
    assert out["invariant"]["alignment"]["mean_error"] < 0.02  # m; the octagon maps to ~5 mm
    bad = cli("run", str(RUNS / "octagon-2laps"), "--linearization", "iekf")
    assert bad.returncode == 2 and "--linearization" in bad.stderr
    assert "Traceback" not in bad.stderr


# What "reproducible" means for data/runs (data/README.md): on any CPU, every file regenerates
# with the same names, headers, row counts and integers, and floats that agree to REGEN_ATOL. The
# writer rounds simulated values to SIMULATED_DECIMALS, so on one machine (and, in practice, on
# any) the CSVs come out byte for byte; the tolerance is what we promise where a last-bit change
# of numpy's SIMD code lands on a rounding boundary. frames.mp4 is compared decoded: its bytes
# depend on the OpenCV build's encoder.
REGEN_ATOL = 2e-9  # two units in the 9th decimal (SIMULATED_DECIMALS)
FRAME_MEAN_ABS_DIFF_MAX = 1.0  # gray levels of 255, per frame
NO_AVX512 = {"NPY_DISABLE_CPU_FEATURES": "AVX512_ICL X86_V4"}  # numpy's pre-AVX-512 paths


def _numbers_close(a: object, b: object, where: str) -> list[str]:
    """Where two parsed JSON values differ beyond REGEN_ATOL (floats) or at all (the rest)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{where}: keys {sorted(a)} != {sorted(b)}"]
        return [d for k in a for d in _numbers_close(a[k], b[k], f"{where}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items != {len(b)}"]
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in _numbers_close(x, y, f"{where}[{i}]")
        ]
    if isinstance(a, float) or isinstance(b, float):
        ok = isinstance(a, int | float) and isinstance(b, int | float) and abs(a - b) <= REGEN_ATOL
        return [] if ok else [f"{where}: {a!r} != {b!r}"]
    return [] if a == b else [f"{where}: {a!r} != {b!r}"]


def _csv_differences(made: Path, kept: Path) -> list[str]:
    made_lines, kept_lines = made.read_text().splitlines(), kept.read_text().splitlines()
    if made_lines[0] != kept_lines[0] or len(made_lines) != len(kept_lines):
        return [
            f"header or row count: {made_lines[0]!r} x{len(made_lines)} != "
            f"{kept_lines[0]!r} x{len(kept_lines)}"
        ]
    problems = []
    for number, (x, y) in enumerate(zip(made_lines, kept_lines, strict=True), start=1):
        if x != y:
            a, b = x.split(","), y.split(",")
            close = len(a) == len(b) and all(
                u == v or (("." in u or "e" in u) and abs(float(u) - float(v)) <= REGEN_ATOL)
                for u, v in zip(a, b, strict=True)
            )
            if not close:
                problems.append(f"line {number}: {x!r} != {y!r}")
    return problems


def _video_differences(made: Path, kept: Path) -> list[str]:
    cv2 = pytest.importorskip("cv2")
    videos = [cv2.VideoCapture(str(made)), cv2.VideoCapture(str(kept))]
    problems, k = [], 0
    try:
        while True:
            (ok_a, a), (ok_b, b) = (v.read() for v in videos)
            if ok_a != ok_b:
                return [f"frame {k}: one video ends here, the other does not"]
            if not ok_a:
                return problems
            diff = float(np.mean(np.abs(a.astype(np.int16) - b.astype(np.int16))))
            if a.shape != b.shape or diff > FRAME_MEAN_ABS_DIFF_MAX:
                problems.append(f"frame {k}: shape {a.shape} vs {b.shape}, mean |diff| {diff:.2f}")
            k += 1
    finally:
        for v in videos:
            v.release()


def data_runs_differences(made_root: Path, kept_root: Path) -> list[str]:
    """What keeps a regenerated data/runs from matching the committed one (see REGEN_ATOL)."""
    rel = lambda root: sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())  # noqa: E731
    if rel(made_root) != rel(kept_root):
        return [f"files: {rel(made_root)} != {rel(kept_root)}"]
    problems = []
    for name in rel(kept_root):
        made, kept = made_root / name, kept_root / name
        if made.read_bytes() == kept.read_bytes():
            continue
        if name.suffix == ".csv":
            found = _csv_differences(made, kept)
        elif name.suffix == ".json":
            found = _numbers_close(json.loads(made.read_text()), json.loads(kept.read_text()), "")
        elif name.suffix == ".mp4":
            found = _video_differences(made, kept)
        else:
            found = ["bytes differ"]
        problems += [f"{name}: {d}" for d in found[:5]]
    return problems


def test_the_regeneration_check_sees_real_differences(tmp_path: Path):
    kept, made = tmp_path / "kept", tmp_path / "made"
    for root, bearing in [(kept, "0.420152841"), (made, "0.420152842")]:
        (root / "run").mkdir(parents=True)
        (root / "run" / "detections.csv").write_text(
            f"t,tag_id,range,bearing\n0.1,3,1.5,{bearing}\n"
        )
        (root / "run" / "run.json").write_text('{"a": [1, 0.5], "name": "x"}')
    assert data_runs_differences(made, kept) == []  # one unit in the 9th decimal: the same run
    (made / "run" / "detections.csv").write_text("t,tag_id,range,bearing\n0.1,4,1.5,0.420152841\n")
    (made / "run" / "run.json").write_text('{"a": [1, 0.5001], "name": "x"}')
    assert data_runs_differences(made, kept) == [
        "run/detections.csv: line 2: '0.1,4,1.5,0.420152841' != '0.1,3,1.5,0.420152841'",
        "run/run.json: .a[1]: 0.5001 != 0.5",
    ]
    (made / "run" / "extra.csv").write_text("t\n")
    assert data_runs_differences(made, kept)[0].startswith("files: ")


@pytest.mark.slow
@pytest.mark.parametrize("simd", ["this-cpu", "no-avx512"])
def test_data_runs_regenerate(tmp_path: Path, simd: str):
    """The committed command rebuilds every file of data/runs (run in a scratch copy), whichever
    SIMD paths numpy takes: on an AVX-512 CPU, "no-avx512" is what an older CPU computes."""
    script = tmp_path / "data" / "runs" / "generate.sh"
    script.parent.mkdir(parents=True)
    script.write_bytes((RUNS / "generate.sh").read_bytes())
    env = {**os.environ, "PYTHON": sys.executable, "MPLBACKEND": "Agg"}  # not python on PATH
    env.pop("NPY_DISABLE_CPU_FEATURES", None)
    env |= NO_AVX512 if simd == "no-avx512" else {}
    out = subprocess.run(
        ["bash", str(script)], capture_output=True, text=True, env=env, timeout=600
    )
    assert out.returncode == 0, out.stderr
    problems = data_runs_differences(script.parent, RUNS)
    assert not problems, "\n".join(problems)


def test_simulate_writes_rounded_values_that_read_back_exactly(tmp_path: Path):
    """The simulator's files carry SIMULATED_DECIMALS: a last-bit change (what another CPU's
    SIMD path makes) writes the same bytes, and what was written reads back bit for bit."""
    from ekfslam import SimulationConfig, simulate, write_run
    from ekfslam.logs.runlog import SIMULATED_DECIMALS, Detections

    run = simulate(SimulationConfig(trajectory="square", laps=1, seed=4))
    d = run.detections
    nudged = Detections(d.t, d.tag_id, np.nextafter(d.range, np.inf), np.nextafter(d.bearing, 9))
    a = write_run(run, tmp_path / "a", decimals=SIMULATED_DECIMALS)
    b = write_run(dataclasses.replace(run, detections=nudged), tmp_path / "b", decimals=9)
    assert (a / "detections.csv").read_bytes() == (b / "detections.csv").read_bytes()
    back = read_run(a)
    np.testing.assert_allclose(back.detections.bearing, d.bearing, rtol=0, atol=5e-10)
    assert not np.array_equal(back.detections.bearing, d.bearing)  # rounded, not exact
    for name in ("detections.csv", "controls.csv", "groundtruth.csv"):
        cells = [c for line in (a / name).read_text().splitlines()[1:] for c in line.split(",")]
        assert "-0.0" not in cells, name  # no sign of zero that a last bit could flip
        decimals = [len(c.split(".")[1]) for c in cells if "." in c and "e" not in c]
        assert max(decimals) <= SIMULATED_DECIMALS, name
    # exact round trip of what was written, rounded again or not
    write_run(back, tmp_path / "c")
    write_run(back, tmp_path / "d", decimals=SIMULATED_DECIMALS)
    for name in ("detections.csv", "controls.csv", "groundtruth.csv"):
        kept = (a / name).read_bytes()
        assert (tmp_path / "c" / name).read_bytes() == kept == (tmp_path / "d" / name).read_bytes()
    out = cli(
        "simulate",
        "--trajectory",
        "square",
        "--laps",
        "1",
        "--seed",
        "4",
        "--out",
        str(tmp_path / "cli"),
    )
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "cli" / "detections.csv").read_bytes() == (a / "detections.csv").read_bytes()


def test_bad_input_is_one_line_exit_two_and_no_traceback(tmp_path: Path):
    run = tmp_path / "broken"
    out = cli("simulate", "--trajectory", "square", "--laps", "1", "--out", str(run))
    assert out.returncode == 0, out.stderr
    lines = (run / "controls.csv").read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[1], "fast", 1)
    (run / "controls.csv").write_text("\n".join(lines) + "\n")
    out = cli("run", str(run))
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
    assert "controls.csv:6:" in out.stderr and "fast" in out.stderr


def test_missing_run_folder_and_mrclam_without_robot(tmp_path: Path):
    out = cli("run", str(tmp_path / "nowhere"))
    assert out.returncode == 2 and "Traceback" not in out.stderr
    (tmp_path / "Barcodes.dat").write_text("# fake\n")
    out = cli("run", str(tmp_path))
    assert out.returncode == 2 and "--robot" in out.stderr


def test_simulate_refuses_to_overwrite(tmp_path: Path):
    target = tmp_path / "r"
    first = cli("simulate", "--trajectory", "octagon", "--laps", "1", "--out", str(target))
    assert first.returncode == 0
    # its own duration is not the command's run time
    assert first.stdout.rstrip().endswith(" s of simulated time")
    again = cli("simulate", "--trajectory", "octagon", "--laps", "1", "--out", str(target))
    assert again.returncode == 2 and "Traceback" not in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1
    # the command line's flag, not the library's keyword
    assert "pass --overwrite to replace" in again.stderr and "overwrite=True" not in again.stderr


def test_only_the_seeds_experiment_prints_the_seeds_row(tmp_path: Path):
    """Regression: `--seed 5` was named octagon-2laps and compared with the seed's real run."""
    made = cli("simulate", "--trajectory", "octagon", "--seed", "5", "--out", str(tmp_path / "r"))
    assert made.returncode == 0, made.stderr
    assert "(octagon-2laps-seed5)" in made.stdout
    out = cli("run", str(tmp_path / "r"))
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[1].startswith("octagon-2laps-seed5 ")
    assert "seed report" not in out.stdout
    as_json = json.loads(cli("run", str(tmp_path / "r"), "--json").stdout)
    assert as_json["seed_report"] is None
    # the shipped run is the seed's experiment, by its run.json, and keeps its row
    shipped = json.loads(cli("run", str(RUNS / "octagon-2laps"), "--json").stdout)
    assert shipped["name"] == "octagon-2laps"
    assert shipped["seed_report"] == {
        "trajectory": "octagon",
        "x0": -0.04,
        "y0": 0.043,
        "theta0": 0.137,
        "mean_error": 0.13,
    }


@pytest.mark.slow
def test_a_map_too_small_to_align_says_why(tmp_path: Path):
    """Regression: a run with a tag map but one landmark seen claimed it had no tag map."""
    from ekfslam.logs.runlog import Detections, RunLog, write_run

    run = read_run(RUNS / "square-2laps")
    keep = run.detections.tag_id == run.detections.tag_id[0]
    d = run.detections
    one_tag = Detections(d.t[keep], d.tag_id[keep], d.range[keep], d.bearing[keep])
    write_run(RunLog(run.meta, run.controls, one_tag, run.groundtruth), tmp_path / "one")
    out = cli("run", str(tmp_path / "one"))
    assert out.returncode == 0, out.stderr
    assert "no known tag map" not in out.stdout
    assert "at least 2 landmarks in common, found 1" in out.stdout
    d = json.loads(cli("run", str(tmp_path / "one"), "--json").stdout)
    assert d["alignment"] is None
    assert "found 1" in d["alignment_note"]


def test_a_closed_pipe_ends_quietly():
    """``python -m ekfslam run RUN | head -1``: the reader leaves early; no traceback, exit 0."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "ekfslam", "run", str(REPO / "data/runs/octagon-2laps"), "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=REPO,
    )
    proc.stdout.close()  # before the replay has printed anything
    stderr = proc.communicate(timeout=120)[1].decode()
    assert proc.returncode == 0, stderr
    assert stderr == ""


def test_a_warning_on_the_command_line_is_one_line(monkeypatch, capsys):
    import warnings

    from ekfslam.cli import main as cli
    from ekfslam.cli import run as run_command

    def warns(args):
        warnings.warn(
            "S was singular for 3 updates;\n  they were skipped", RuntimeWarning, stacklevel=1
        )
        return 0

    monkeypatch.setattr(run_command, "cmd_run", warns)
    assert cli.main(["run", str(REPO / "data/runs/octagon-2laps")]) == 0
    assert capsys.readouterr().err == "warning: S was singular for 3 updates; they were skipped\n"


def test_warm_fills_the_cache_and_marks_it(tmp_path: Path):
    """``python -m ekfslam warm`` leaves the marker by which backend "auto" loads the compiled
    steps instead of compiling them (`ekfslam.core.filter.compile.warm_stamp`)."""
    out = run_ekfslam("warm")
    assert out.returncode == 0, out.stderr
    assert "the filter's compiled steps are in the cache" in out.stdout
    compiler = importlib.import_module(COMPILER)  # numba: this test only
    assert compiler.warm_stamp(ROOTS, models_of(ODOMETRY, RANGE_BEARING)).exists()


def test_a_run_without_sightings_says_it_cannot_be_judged(tmp_path: Path):
    """Regression: a run whose detections.csv held only its header printed "diagnosis: ok"."""
    run = tmp_path / "run"
    run.mkdir()
    for name in ("run.json", "controls.csv", "groundtruth.csv"):
        (run / name).write_bytes((RUNS / "octagon-2laps" / name).read_bytes())
    (run / "detections.csv").write_text("t,tag_id,range,bearing\n")
    out = cli("run", str(run))
    assert out.returncode == 0, out.stderr  # the replay itself is sound: odometry alone
    assert "diagnosis: suspect" in out.stdout and "no sighting was tested" in out.stdout
    assert "no alignment" in out.stdout
