"""``run --association``: the flag, its JSON block, and its one-line refusal."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from ekfslam_cli import run_ekfslam

from ekfslam.cli.run import _map_noise
from ekfslam.logs.mrclam.defaults import MRCLAM_MAP_NOISE, NAME
from ekfslam.logs.runlog import read_run

REPO = Path(__file__).resolve().parents[2]
OCTAGON = REPO / "data" / "runs" / "octagon-2laps"


cli = run_ekfslam


def test_jcbb_adds_the_association_block_and_known_does_not():
    hidden = cli("run", str(OCTAGON), "--association", "jcbb", "--json")
    assert hidden.returncode == 0, hidden.stderr
    out = json.loads(hidden.stdout)
    block = out["association"]
    for key in ("method", "correct", "wrong", "new", "ambiguous", "correct_fraction", "noise"):
        assert key in block
    assert block["method"] == "jcbb"
    assert block["correct_fraction"] >= 0.99
    assert "association mapping" in block["alignment_matching"]
    known = json.loads(cli("run", str(OCTAGON), "--json").stdout)
    assert "association" not in known  # the default's output is as it was
    assert known.keys() | {"association"} == out.keys()


def test_the_table_says_how_it_associated_and_a_bad_method_is_one_line():
    text = cli("run", str(OCTAGON), "--association", "nn").stdout
    assert "association nn: correct" in text and "association mapping" in text
    bad = cli("run", str(OCTAGON), "--association", "guess")
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "--association" in bad.stderr


def test_match_by_position_says_so_and_finds_the_mappings_map():
    """The octagon's eight tags are far apart: matching by position pairs them as the mapping."""
    by_map = json.loads(cli("run", str(OCTAGON), "--association", "jcbb", "--json").stdout)
    out = cli("run", str(OCTAGON), "--association", "jcbb", "--match", "position", "--json")
    assert out.returncode == 0, out.stderr
    by_position = json.loads(out.stdout)
    assert "robust fit" in by_position["association"]["alignment_matching"]
    assert by_position["alignment"] == by_map["alignment"]
    bad = cli("run", str(OCTAGON), "--match", "position")  # known ids: nothing to match
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "--match" in bad.stderr


def test_map_noise_feeds_the_decisions_to_a_second_filter_and_says_so():
    """The seed's runs map with the deciding filter unless asked; asked, the JSON says with what."""
    plain = json.loads(cli("run", str(OCTAGON), "--association", "jcbb", "--json").stdout)
    assert plain["association"]["map_noise"] is None
    out = cli("run", str(OCTAGON), "--association", "jcbb", "--map-noise", "mrclam", "--json")
    assert out.returncode == 0, out.stderr
    mapped = json.loads(out.stdout)
    assert mapped["association"]["map_noise"] == {
        "sigma_x": 0.005,
        "sigma_y": 0.005,
        "sigma_theta": 0.05,
        "sigma_range": 0.5,
        "sigma_bearing": 0.03,
    }
    assert mapped["association"]["correct"] == plain["association"]["correct"] == 614
    assert mapped["association"]["noise"] == plain["association"]["noise"]  # the deciding one
    assert mapped["alignment"] != plain["alignment"]
    cases = [
        (("--map-noise", "mrclam"), "--association"),
        (("--association", "jcbb", "--map-noise", "x005"), "--map-noise"),
    ]
    for bad_args, word in cases:
        bad = cli("run", str(OCTAGON), *bad_args)
        assert bad.returncode == 2
        assert bad.stderr.count("\n") == 1 and "--map-noise" in bad.stderr and word in bad.stderr
        assert "Traceback" not in bad.stderr


def test_run_maps_as_score_mrclam_does_by_default():
    """`run DATASET --robot N --association X` gives score-mrclam's row: on a MRCLAM run the
    default (auto) is the mapping filter with `MRCLAM_MAP_NOISE`; on the seed's runs none."""
    seed = read_run(OCTAGON)
    robot = replace(seed, meta=replace(seed.meta, defaults=NAME))  # what load_mrclam names
    assert _map_noise(seed, "auto") is None
    assert _map_noise(robot, "auto") == MRCLAM_MAP_NOISE
    assert _map_noise(robot, "none") is None and _map_noise(seed, "mrclam") == MRCLAM_MAP_NOISE


def test_passes_decide_again_and_say_which_pass_the_map_is():
    out = cli("run", str(OCTAGON), "--association", "jcbb", "--passes", "2", "--json")
    assert out.returncode == 0, out.stderr
    passes = json.loads(out.stdout)["passes"]
    assert passes["chosen"] == 2 and [p["changed"] for p in passes["each"]] == [-1, 8]
    text = cli("run", str(OCTAGON), "--association", "jcbb", "--passes", "2").stdout
    assert "passes: the map of pass 2 of 2 (decisions changed per pass: 8)" in text
    one = json.loads(cli("run", str(OCTAGON), "--association", "jcbb", "--json").stdout)
    assert "passes" not in one  # one pass: the output is as it was


def test_a_bad_number_of_passes_is_one_line():
    for words in (
        ("--association", "jcbb", "--passes", "0"),
        ("--passes", "x"),
        ("--association", "jcbb", "--passes", "11"),
        ("--passes", "2"),
    ):
        bad = cli("run", str(OCTAGON), *words)
        assert bad.returncode == 2, words
        assert bad.stderr.count("\n") == 1 and "--passes" in bad.stderr, bad.stderr


def test_run_passes_the_time_error_and_the_founding_rule_to_the_replay(monkeypatch, capsys):
    """`run --association X --time-error T --new-rule R` replays with them; unset, with the
    source's time error (exact on the seed's runs) and the method's own founding."""
    from ekfslam import pipeline
    from ekfslam.cli.main import main

    seen = []
    real = pipeline.replay

    def spy(*args, **kwargs):
        seen.append(kwargs["association"].association)  # a HiddenIds: its AssociationConfig
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "replay", spy)
    base = ["run", str(OCTAGON), "--json"]
    assert (
        main([*base, "--association", "mht", "--time-error", "shared", "--new-rule", "density"])
        == 0
    )
    assert main([*base, "--association", "jcbb"]) == 0
    capsys.readouterr()
    (mht, jcbb) = seen
    assert (mht.method, mht.time_shared, mht.new_rule) == ("mht", True, "density")
    assert (jcbb.time_shared, jcbb.new_rule, jcbb.time_sigma) == (False, "density", 0.0)
    out = cli("run", str(OCTAGON), "--association", "mht", "--time-error", "shared", "--json")
    block = json.loads(out.stdout)["association"]  # the JSON says what it replayed with
    assert block["new_rule"] == "threshold"  # mht's own
    assert block["time_error"] == {"sigma": 0.0, "form": "shared"}


def test_hide_ids_is_auto_and_says_which_association_it_used_and_why():
    """Issue 39: ``--hide-ids`` (``--association auto``) replays with jcbb, escalating only where
    its diagnosis is not ok; the octagon's is, so jcbb is kept, all of it right."""
    text = cli("run", str(OCTAGON), "--hide-ids")
    assert text.returncode == 0, text.stderr
    assert "association: auto used jcbb (its diagnosis is ok)" in text.stdout.splitlines()
    doc = json.loads(cli("run", str(OCTAGON), "--association", "auto", "--json").stdout)
    assert doc["association"]["method"] == "jcbb"
    assert doc["association"]["correct_fraction"] >= 0.99
    assert doc["association"]["auto"]["used"] == "jcbb"
    assert doc["association"]["auto"]["escalated"] is False
    assert [t["verdict"] for t in doc["association"]["auto"]["tried"]] == ["ok"]


def test_auto_with_passes_is_one_line():
    out = cli("run", str(OCTAGON), "--association", "auto", "--passes", "2")
    assert out.returncode == 2
    assert "argument --passes: auto chooses its replays; name a method" in out.stderr
    assert "Traceback" not in out.stderr
