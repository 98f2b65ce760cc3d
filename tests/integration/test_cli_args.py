"""The command line's option types, its one-line parser errors, and the atomic writer."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import stat
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from benchmarks.__main__ import COMMANDS as BENCHMARKS
from ekfslam import files, read_run
from ekfslam.cli import animate as animate_args
from ekfslam.cli import args as ca
from ekfslam.cli.main import build_parser, main
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import ConfigError, EkfSlamError
from ekfslam.sim.simulation import SimulationConfig

RUN = Path(__file__).resolve().parents[2] / "data" / "runs" / "octagon-2laps"


def _refused(parse, text: str) -> str:
    with pytest.raises(argparse.ArgumentTypeError) as info:
        parse(text)
    return str(info.value)


@pytest.mark.parametrize(
    ("parse", "text", "message"),
    [
        (ca.positive(), "0", "must be > 0, got 0"),
        (ca.positive(), "-2.5", "must be > 0, got -2.5"),
        (ca.non_negative(), "-1", "must be >= 0, got -1"),
        (ca.non_negative(10.0, why="m"), "1e200", "must be at most 10 (m), got 1e200"),
        (ca.real(), "nan", "must be a finite number, got nan"),
        (ca.real(), "-inf", "must be a finite number, got -inf"),
        (ca.real(), "1e400", "must be a finite number, got 1e400"),  # float() gives inf
        (ca.real(), "abc", "must be a number, got 'abc'"),
        (ca.probability(), "1.5", "must be at most 1 (a probability), got 1.5"),
        (ca.finite(2.0), "-3", "must be between -2 and 2, got -3"),
        (ca.whole(1, 9), "0", "must be >= 1, got 0"),
        (ca.whole(1, 9), "10", "must be at most 9, got 10"),
        (ca.whole(1, 9), "2.0", "must be a whole number, got '2.0'"),
        (ca.whole(2, 9, also=(0,)), "1", "must be >= 2 or 0, got 1"),
        (ca.seed(), "-1", "must be >= 0, got -1"),
        (ca.one_of(range(1, 4), "robots"), "4", "robots are 1, 2, 3; got '4'"),
        (ca.regex, "(", "not a valid regular expression"),
        (ca.non_empty, " ", "must not be empty"),
    ],
)
def test_types_refuse_with_the_bound_and_the_value(parse, text, message):
    assert message in _refused(parse, text)


def test_types_accept_the_edges_of_their_ranges():
    assert ca.positive(10.0)("10") == 10.0
    assert ca.non_negative()("0") == 0.0
    assert ca.probability()("0") == 0.0 and ca.probability()("1") == 1.0
    assert ca.whole(2, 9, also=(0,))("0") == 0
    assert ca.whole(1, 9)("9") == 9
    assert ca.finite(2.0)("-2") == -2.0
    assert ca.one_of(range(1, 4), "robots")("3") == 3


def test_output_file_checks_format_folder_and_parent(tmp_path):
    plot = ca.output_file(ca.PLOT_FORMATS)
    assert plot(str(tmp_path / "new" / "deeper" / "fig.PNG")) == tmp_path / "new/deeper/fig.PNG"
    assert "no extension" in _refused(plot, str(tmp_path / "figure"))
    assert "'.xyz'" in _refused(plot, str(tmp_path / "fig.xyz"))
    (tmp_path / "folder.png").mkdir()
    assert "is a folder" in _refused(plot, str(tmp_path / "folder.png"))
    (tmp_path / "file").write_text("x")
    assert "which is a file" in _refused(plot, str(tmp_path / "file" / "sub" / "fig.png"))
    assert not (tmp_path / "new").exists()  # checking creates nothing


def test_output_folder_refuses_a_file_and_paths_under_one(tmp_path):
    (tmp_path / "file").write_text("x")
    assert ca.output_folder(str(tmp_path / "a" / "b")) == tmp_path / "a" / "b"
    assert "not a folder" in _refused(ca.output_folder, str(tmp_path / "file"))
    assert "which is a file" in _refused(ca.output_folder, str(tmp_path / "file" / "x"))


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_output_checks_refuse_a_read_only_folder(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert "permission denied" in _refused(ca.output_folder, str(locked / "out"))
    finally:
        locked.chmod(0o700)


def test_parser_error_is_one_line_with_a_help_hint(capsys):
    parser = ca.Parser(prog="prog")
    parser.add_argument("--n", type=ca.whole(1, 5))
    with pytest.raises(SystemExit) as info:
        parser.parse_args(["--n", "7"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err == "prog: error: argument --n: must be at most 5, got 7 (see prog --help)\n"


def test_parser_checks_run_after_parsing(capsys):
    parser = ca.Parser(prog="prog")
    parser.add_argument("--a", type=int, default=0)
    parser.add_check(lambda args: "argument --a: must be even" if args.a % 2 else None)
    assert parser.parse_args(["--a", "2"]).a == 2
    with pytest.raises(SystemExit):
        parser.parse_args(["--a", "3"])
    assert capsys.readouterr().err.count("\n") == 1


def test_atomic_write_replaces_and_keeps_the_mode_of_a_plain_file(tmp_path):
    path = tmp_path / "sub" / "out.txt"
    files.atomic_write_text(path, "one\n")
    assert path.read_text() == "one\n"
    plain = tmp_path / "plain.txt"
    plain.write_text("")
    assert stat.S_IMODE(path.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)
    files.atomic_write_text(path, "two\n")
    assert path.read_text() == "two\n"
    assert sorted(p.name for p in path.parent.iterdir()) == ["out.txt"]


def test_a_failed_write_leaves_no_file_and_keeps_the_old_one(tmp_path):
    path = tmp_path / "out.txt"

    def half_then_fail(tmp: Path) -> None:
        tmp.write_text("half a fi")
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        files.atomic_write(path, half_then_fail)
    assert list(tmp_path.iterdir()) == []  # no file, no temporary
    path.write_text("old\n")

    def interrupted(tmp: Path) -> None:
        tmp.write_text("new, but only ha")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        files.atomic_write(path, interrupted)
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_save_figure_writes_the_format_its_suffix_names(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    try:
        assert files.save_figure(fig, tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
        assert files.save_figure(fig, tmp_path / "f.pdf").read_bytes()[:4] == b"%PDF"
        assert b"<svg" in files.save_figure(fig, tmp_path / "f.svg").read_bytes()[:400]
    finally:
        plt.close(fig)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.pdf", "f.png", "f.svg"]


@pytest.mark.parametrize(
    "make",
    [
        lambda: NoiseConfig(sigma_range=0.0),
        lambda: NoiseConfig(sigma_x=float("nan")),
        lambda: FilterConfig(gate=-1.0),
        lambda: FilterConfig(reinit_after=1),
        lambda: SimulationConfig(laps=0),
        lambda: SimulationConfig(size=-1.0),
    ],
)
def test_config_errors_are_ours_and_still_value_errors(make):
    with pytest.raises(ConfigError) as info:
        make()
    assert isinstance(info.value, EkfSlamError) and isinstance(info.value, ValueError)


def test_main_returns_2_for_a_bad_option_and_for_a_config_error(tmp_path, capsys, monkeypatch):
    assert main(["run", str(RUN), "--sigma-range", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sigma-range" in err[0]

    def refuse(*args, **kwargs):
        raise ConfigError("NoiseConfig.sigma_x must be a finite non-negative number")

    monkeypatch.setattr(sys.modules["ekfslam.pipeline"], "replay", refuse)
    assert main(["run", str(RUN)]) == 2
    assert capsys.readouterr().err == (
        "error: NoiseConfig.sigma_x must be a finite non-negative number\n"
    )


def test_run_plot_into_new_folders_reports_the_real_path(tmp_path, capsys):
    run = shutil.copytree(RUN, tmp_path / "run")
    plot = tmp_path / "figs" / "a" / "fig2.pdf"
    assert main(["run", str(run), "--plot", str(plot), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["plot"] == str(plot)
    assert plot.read_bytes()[:4] == b"%PDF"
    assert [p.name for p in plot.parent.iterdir()] == ["fig2.pdf"]


def test_tum_out_into_new_folders(tmp_path, capsys):
    out = tmp_path / "a" / "b"
    assert main(["tum", str(RUN), "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert "trajectory.tum" in names and not any(n.startswith(".") for n in names)


@pytest.mark.slow
def test_detect_out_into_a_missing_folder_writes_there(tmp_path, capsys):
    run = shutil.copytree(RUN.parent / "square-1lap-frames", tmp_path / "run")
    out = tmp_path / "new" / "folder" / "det.csv"
    assert main(["detect", str(run), "--out", str(out)]) == 0
    assert out.read_text().startswith("t,tag_id,range,bearing\n")
    assert f"wrote {out}:" in capsys.readouterr().out


def test_a_mrclam_dataset_is_a_folder_or_a_number(tmp_path):
    assert ca.mrclam_dataset(str(tmp_path)) == tmp_path
    assert ca.mrclam_dataset("7") == 7 and ca.mrclam_dataset("1") == 1
    for bad, says in [("0", "1 to 9"), ("10", "1 to 9"), (str(tmp_path / "no"), "does not exist")]:
        with pytest.raises(argparse.ArgumentTypeError, match=says):
            ca.mrclam_dataset(bad)
    (tmp_path / "f.txt").write_text("x")
    with pytest.raises(argparse.ArgumentTypeError, match="is not a folder"):
        ca.mrclam_dataset(str(tmp_path / "f.txt"))


@pytest.mark.slow
def test_run_animate_writes_a_gif_of_the_frames_asked_for(tmp_path, capsys):
    movie = tmp_path / "movies" / "octagon.gif"
    assert (
        main(["run", str(RUN), "--animate", str(movie), "--frames", "6", "--fps", "4", "--json"])
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert (out["animation"], out["animation_frames"]) == (str(movie), 6)
    with Image.open(movie) as gif:
        assert gif.format == "GIF" and gif.n_frames == 6 and gif.info["duration"] == 250
    assert [p.name for p in movie.parent.iterdir()] == ["octagon.gif"]


def test_run_animate_mp4_without_ffmpeg_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(animate_args, "has_ffmpeg", lambda: False)
    monkeypatch.setattr(sys.modules["ekfslam.pipeline"], "replay", _never)
    assert main(["run", str(RUN), "--animate", str(tmp_path / "a.mp4")]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert "--animate: writing .mp4 needs ffmpeg: pip install imageio-ffmpeg" in line
    assert not list(tmp_path.iterdir())


def _never(*args, **kwargs):
    raise AssertionError("the replay ran although the command line was refused")


@pytest.mark.slow
def test_run_animate_with_hidden_ids_labels_landmarks_by_true_id(tmp_path, monkeypatch):
    from ekfslam.viz import animation  # matplotlib: only this test needs it

    seen = {}

    def capture(frames, path, fps):
        seen["labels"], seen["fps"] = frames.landmark_labels, fps
        return path

    monkeypatch.setattr(animation, "save_animation", capture)
    square = RUN.parent / "square-2laps"
    args = ["run", str(square), "--association", "nn", "--animate", str(tmp_path / "a.gif")]
    assert main([*args, "--frames", "3", "--json"]) == 0
    ids = np.asarray(read_run(square).detections.tag_id)
    first_seen = [str(i) for i in dict.fromkeys(ids.tolist())]  # nn gets every one right here
    assert seen == {"labels": first_seen, "fps": 10.0}


@pytest.mark.parametrize(
    ("argv", "line"),
    [
        (
            ["bench", "--mrclam", "7", "--no-mrclam"],
            "argument --no-mrclam: contradicts --mrclam, given too; give one of them",
        ),
        (
            ["bench", "--no-mr", "--mrclam", "7"],
            "argument --no-mr: contradicts --mrclam, given too; give one of them",
        ),
        (
            ["run", "RUN", "--robot", "1", "--robot", "2"],
            "argument --robot: given twice with different values (--robot 1 and --robot 2); "
            "give it once",
        ),
        (
            ["run", "RUN", "--start", "0", "0", "0", "--start", "1", "-1", "0"],
            "argument --start: given twice with different values (--start 0 0 0 and --start 1 "
            "-1 0); give it once",
        ),
        (
            ["run", "RUN", "--sigma-range=0.1", "--sigma-range", "0.2"],
            "argument --sigma-range: given twice with different values (--sigma-range 0.1 and "
            "--sigma-range 0.2); give it once",
        ),
    ],
)
def test_contradicting_options_are_refused_not_resolved_silently(argv, line, capsys) -> None:
    argv = [str(RUN) if a == "RUN" else a for a in argv]
    prog = "python -m benchmarks" if argv[0] in BENCHMARKS else "python -m ekfslam"
    table = {"commands": BENCHMARKS, "prog": prog} if argv[0] in BENCHMARKS else {}
    assert main(argv, **table) == 2
    err = capsys.readouterr().err
    assert f": error: {line} (see {prog} {argv[0]} --help)" in err, err


def test_an_option_repeated_with_the_same_value_is_harmless() -> None:
    argv = ["run", str(RUN), "--json", "--json", "--start", "-0.1", "0", "0"]
    args = build_parser(argv).parse_args([*argv, "--start", "-0.1", "0", "0"])
    assert args.json and args.start == [-0.1, 0.0, 0.0]
