"""Where a move's time went in the browser (`pieces`), from the stamps the page recorded."""

from __future__ import annotations

import pytest

from benchmarks.browser import PIECES, pieces


class Page:
    """The two arrays `pieces` reads: the split's stamps (ms) and the canvas repaints."""

    def __init__(self, split: dict, draws: list[float]) -> None:
        self.result = [split, draws]

    def evaluate(self, script: str):
        return self.result


def move(t0: float) -> dict:
    """One move at t0: key, send, two replies (status 1 KiB, frame 50 KiB), blob, copy, load."""
    return {
        "keys": [t0],
        "sends": [t0 + 1],
        "recvs": [[t0 + 11, 1024], [t0 + 41, 50 * 1024], [t0 + 90, 2048]],
        "blobs": [[t0 + 42, 50 * 1024]],
        "copies": [[t0 + 42.5, 4.0]],
        "loads": [t0 + 55],
    }


def test_each_piece_is_the_median_over_the_moves():
    a, b = move(0.0), move(1000.0)
    b["loads"] = [1000.0 + 65]  # a slower load on the second move
    split = {k: a[k] + b[k] for k in a}
    got = pieces(Page(split, [58.0, 1069.0]))
    assert list(got) == list(PIECES)
    assert got["key_to_send"] == 1.0
    assert got["send_to_reply"] == 10.0
    assert got["reply_to_frame"] == 30.0  # the largest message is the frame
    assert got["frame_to_blob"] == 1.0
    assert got["png_copy"] == 4.0
    assert got["blob_to_loaded"] == pytest.approx(18.0)  # median of 13 and 23
    assert got["loaded_to_painted"] == pytest.approx(3.5)  # median of 3 and 4
    assert got["frame_kib"] == 50.0


def test_a_move_without_a_frame_is_left_out():
    split = move(0.0)
    split["blobs"] = []
    assert pieces(Page(split, [58.0])) == {}
