"""What the student feels: from a slider key press to the figure's pixels changing, in a browser.

`measure_moves` drives a page that shows the live panel (JupyterLab or Voila, any Playwright page)
and times, for each move, the key press (the page's own ``keydown`` clock) to the first frame in
which ipympl's canvas is drawn again (a wrapped ``drawImage``, stamped at the next animation
frame, when the new pixels are painted). It also checks, by a hash of the canvas pixels, that
the figure changed for every move. The browser test uses it (and prints what it measured);
`browser_benchmark` serves generated notebooks from one Voila server and times the panel's
redraw strategies alternately in the same run (the machine is shared: only the comparison
within one run means much). ``python -m benchmarks tune --browser`` prints it.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import secrets
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Debian's Chromium (Playwright's own browser download is never used).
CHROMIUM = Path(os.environ.get("EKFSLAM_CHROMIUM", "/usr/bin/chromium"))
#: As root in a sandbox with no network: no setuid sandbox, no GPU, and no background requests
#: (without these Chromium keeps opening connections that the machine refuses).
CHROMIUM_ARGS = (
    "--no-sandbox --disable-gpu --disable-dev-shm-usage --disable-quic --no-first-run "
    "--disable-background-networking --disable-component-update --disable-sync "
    "--disable-default-apps --disable-extensions"
).split()

# Installed once per page. ipympl paints its view canvas from an offscreen canvas with
# drawImage; the offscreen one is not in the document, so `closest` keeps only what is shown.
_INSTALL = """() => {
  if (window.__ekfslamLatency) return;
  const st = window.__ekfslamLatency = {draws: [], keys: []};
  const drawImage = CanvasRenderingContext2D.prototype.drawImage;
  CanvasRenderingContext2D.prototype.drawImage = function (...args) {
    const out = drawImage.apply(this, args);
    if (this.canvas.closest && this.canvas.closest('.jupyter-matplotlib-canvas-div')) {
      requestAnimationFrame(() => st.draws.push(performance.now()));
    }
    return out;
  };
  document.addEventListener('keydown', () => st.keys.push(performance.now()), true);
}"""
_HASH = """() => {
  const c = document.querySelector('.jupyter-matplotlib-canvas-div canvas');
  const px = new Uint32Array(c.getContext('2d').getImageData(0, 0, c.width, c.height).data.buffer);
  let h = 2166136261;
  for (let i = 0; i < px.length; i++) h = Math.imul(h ^ px[i], 16777619);
  return (h >>> 0).toString(16) + '/' + c.width + 'x' + c.height;
}"""
_STATE = """() => [window.__ekfslamLatency.keys.slice(-1)[0] ?? null,
  window.__ekfslamLatency.draws.slice(),
  document.querySelector('.ekfslam-timing')?.innerText ?? '']"""
# Installed before a page loads (`open_panel`): where a move's time goes in the browser. The
# kernel's websocket is wrapped from its creation; ipympl turns each frame into a PNG blob
# URL for an Image, and copies its canvas with toDataURL on every frame.
_SPLIT = """(() => {
  const T = window.__ekfslamSplit = {keys: [], sends: [], recvs: [], blobs: [], loads: [],
                                     copies: []};
  document.addEventListener('keydown', () => T.keys.push(performance.now()), true);
  const send = WebSocket.prototype.send;
  WebSocket.prototype.send = function (d) {
    T.sends.push(performance.now());
    return send.call(this, d);
  };
  window.WebSocket = class extends window.WebSocket {  // (keeps OPEN, CLOSED, ... and instanceof)
    constructor(...a) {
      super(...a);
      this.addEventListener('message', (e) => T.recvs.push([performance.now(),
        typeof e.data === 'string' ? e.data.length : (e.data.byteLength ?? e.data.size)]));
    }
  };
  const blob = URL.createObjectURL;
  URL.createObjectURL = function (b) {
    if (b && b.type === 'image/png') T.blobs.push([performance.now(), b.size]);
    return blob.call(this, b);
  };
  const copy = HTMLCanvasElement.prototype.toDataURL;
  HTMLCanvasElement.prototype.toDataURL = function (...a) {
    const t0 = performance.now(), out = copy.apply(this, a);
    T.copies.push([t0, performance.now() - t0]);
    return out;
  };
  const src = Object.getOwnPropertyDescriptor(HTMLImageElement.prototype, 'src');
  Object.defineProperty(HTMLImageElement.prototype, 'src', {
    set(v) {
      if (String(v).startsWith('blob:')) {
        this.addEventListener('load', () => T.loads.push(performance.now()), {once: true});
      }
      src.set.call(this, v);
    },
    get() { return src.get.call(this); },
  });
})();"""
#: The pieces `pieces` reports, in the order a move goes through them (ms).
PIECES = (
    "key_to_send",
    "send_to_reply",
    "reply_to_frame",
    "frame_to_blob",
    "png_copy",
    "blob_to_loaded",
    "loaded_to_painted",
    "frame_kib",
)

#: A move is over when the kernel reported a new replay and the canvas was quiet this long (s).
QUIET_S = 0.4


@dataclass(frozen=True)
class Move:
    """One key press: its latency to the first repaint (ms), and whether the pixels changed."""

    key: str
    latency_ms: float
    changed: bool
    repaints: int


def measure_moves(page, moves: int = 20, slider: str = "Q: σr", timeout: float = 60.0):
    """Press ArrowLeft, ArrowRight, ... on the panel's `slider` `moves` times, one at a time.

    page : a Playwright page showing a drawn `ekfslam.ui.widgets.TuningPanel`.
    Returns a list of `Move`. Each move waits until the panel's timing line shows a new replay
    and the canvas has been quiet for `QUIET_S`, so one move's redraw never counts for the next.
    Raises TimeoutError when a move shows no repaint within `timeout` s.
    """
    return measure_together([page], moves, slider, timeout)[0]


def measure_together(pages, moves: int = 20, slider: str = "Q: σr", timeout: float = 60.0):
    """`measure_moves` on several pages at once: each move presses the key on every page in
    turn (a class moving its sliders together), then waits until every page has redrawn.

    Returns one list of `Move` per page, each timed from that page's own key press.
    """
    handles = []
    for page in pages:
        page.evaluate(_INSTALL)
        handles.append(page.locator(".widget-slider", has_text=slider).locator(".noUi-handle"))
    out: list[list[Move]] = [[] for _ in pages]
    for k in range(moves):
        key = ("ArrowLeft", "ArrowRight")[k % 2]
        before = [(page.evaluate(_HASH), page.evaluate(_STATE)) for page in pages]
        for handle in handles:
            handle.focus()
            handle.press(key)
        pending, deadline = set(range(len(pages))), time.monotonic() + timeout
        while pending:
            for i in sorted(pending):
                page, (hash0, (_, draws0, timing0)) = pages[i], before[i]
                pressed, draws, timing = page.evaluate(_STATE)
                new = [t for t in draws[len(draws0) :] if pressed is not None and t >= pressed]
                if new and timing != timing0 and performance_quiet(page, draws[-1]):
                    changed = page.evaluate(_HASH) != hash0
                    out[i].append(Move(key, new[0] - pressed, changed, len(new)))
                    pending.discard(i)
            if pending and time.monotonic() > deadline:
                raise TimeoutError(f"move {k + 1} ({key}): no repaint after {timeout:.0f} s")
            time.sleep(0.05)
    return out


def pieces(page) -> dict[str, float]:
    """Medians over the moves measured on `page` (opened by `open_panel`) of where the time
    from the key press to the repaint went (ms; `PIECES`): the key to the websocket message,
    to the kernel's first reply (the server's and kernel's reading), to the frame (the largest
    message: the kernel's replay, drawing and PNG), to ipympl's blob URL, ipympl's own copy
    of its canvas (toDataURL, on every frame), the blob loaded as an image, and painted; and
    the frame's size (KiB). Moves whose trail is incomplete are left out."""
    t, draws = page.evaluate("() => [window.__ekfslamSplit, window.__ekfslamLatency.draws]")
    rows = []
    for k, key in enumerate(t["keys"]):
        end = t["keys"][k + 1] if k + 1 < len(t["keys"]) else math.inf
        sends = [x for x in t["sends"] if key <= x < end]
        blobs = [b for b in t["blobs"] if key <= b[0] < end]
        if not sends or not blobs:
            continue
        blob = blobs[0][0]
        recvs = [r for r in t["recvs"] if sends[0] <= r[0] <= blob]
        loads = [x for x in t["loads"] if blob <= x < end]
        painted = [x for x in draws if loads and loads[0] <= x < end]
        if not recvs or not painted:
            continue
        frame = max(recvs, key=lambda r: r[1])
        copy = sum(d for t0, d in t["copies"] if blob <= t0 < loads[0])
        rows.append(
            (
                sends[0] - key,
                recvs[0][0] - sends[0],
                frame[0] - recvs[0][0],
                blob - frame[0],
                copy,
                loads[0] - blob,
                painted[0] - loads[0],
                frame[1] / 1024,
            )
        )
    if not rows:
        return {}
    return dict(zip(PIECES, np.median(np.array(rows), axis=0).tolist(), strict=True))


def performance_quiet(page, last_draw: float) -> bool:
    """Whether the page's clock is `QUIET_S` past `last_draw` (both in performance.now() ms)."""
    return page.evaluate("() => performance.now()") - last_draw > QUIET_S * 1e3


def stats(moves: Sequence[Move]) -> dict[str, float]:
    """Median and 90th percentile of the latencies (ms), the number of moves and of changes."""
    ms = np.array([m.latency_ms for m in moves])
    return {
        "median_ms": float(np.median(ms)),
        "p90_ms": float(np.percentile(ms, 90)),
        "moves": len(moves),
        "changed": sum(m.changed for m in moves),
    }


def jupyter_home(tmp: Path) -> dict[str, str]:
    """Environment for a Jupyter server whose every config and data folder is under `tmp`."""
    env = dict(os.environ)
    folders = {
        "JUPYTER_CONFIG_DIR": "config",
        "JUPYTER_DATA_DIR": "data",
        "JUPYTER_RUNTIME_DIR": "runtime",
        "JUPYTERLAB_SETTINGS_DIR": "settings",
        "JUPYTERLAB_WORKSPACES_DIR": "workspaces",
        "IPYTHONDIR": "ipython",
    }
    for var, sub in folders.items():
        (tmp / sub).mkdir(parents=True, exist_ok=True)
        env[var] = str(tmp / sub)
    env["PYDEVD_DISABLE_FILE_VALIDATION"] = "1"
    return env


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def panel_notebook(setup: str) -> dict:
    """A three-cell notebook: ipympl and the panel's import, `setup` (defines ``panel``), panel."""
    cells = ["%matplotlib widget\nfrom ekfslam.ui.widgets import tuning_panel", setup, "panel"]
    kernel = {"name": "python3", "display_name": "Python 3", "language": "python"}
    code = {"cell_type": "code", "metadata": {}, "outputs": [], "execution_count": None}
    return {
        "cells": [{**code, "id": f"cell{k}", "source": s} for k, s in enumerate(cells)],
        "metadata": {"kernelspec": kernel},
        "nbformat": 4,
        "nbformat_minor": 5,
    }


@contextlib.contextmanager
def voila_server(
    folder: Path, tmp: Path, startup_s: float = 120.0, pythonpath: str | None = None
) -> Iterator[str]:
    """A Voila server on 127.0.0.1 over `folder` until the block ends; yields its base URL.
    With `pythonpath`, its kernels import ekfslam from there (another checkout)."""
    port, token = free_port(), secrets.token_hex(16)
    cmd = [sys.executable, "-m", "voila", str(folder), "--no-browser", "--Voila.ip=127.0.0.1"]
    cmd += [f"--port={port}", f"--token={token}"]
    log = tmp / "voila.log"
    with open(log, "wb") as out:
        env = jupyter_home(tmp)
        if pythonpath is not None:
            env["PYTHONPATH"] = pythonpath
        proc = subprocess.Popen(
            cmd, env=env, cwd=folder, stdout=out, stderr=subprocess.STDOUT, start_new_session=True
        )
    try:
        deadline = time.monotonic() + startup_s
        while True:
            with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 2):
                break
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"voila did not start:\n{log.read_text()[-3000:]}")
            time.sleep(0.5)
        yield f"http://127.0.0.1:{port}", token, proc.pid
    finally:
        proc.terminate()  # Voila shuts its kernels down on SIGTERM
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


def open_panel(browser, base: str, token: str, name: str):
    """A new page showing ``{name}.ipynb`` as served by `voila_server`, once its figure is drawn."""
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    page.add_init_script(_SPLIT)
    page.goto(f"{base}/voila/render/{name}.ipynb?token={token}", timeout=240_000)
    page.wait_for_selector(".ekfslam-timing", timeout=240_000)
    page.wait_for_selector(".jupyter-matplotlib-canvas-div canvas", timeout=60_000)
    time.sleep(1.0)  # the first full frame
    return page


def browser_benchmark(
    setups: dict[str, str], moves: int = 20, rounds: int = 2, against: Path | None = None
) -> dict:
    """Latency per notebook setup, measured alternately in one Voila server and one browser.

    setups : {label: a code cell that defines ``panel``}, e.g. ``panel = tuning_panel(blit=False)``.
    Each label gets its own page (and kernel); the pages take turns, `moves` // `rounds` moves at a
    time, so a busy spell on the shared machine hits every setup alike. With `against` (another
    checkout's folder), each setup also runs from a second server whose kernels import that
    checkout's ekfslam, labelled ``"{label} ({against.name})"``, its turn right after or (every
    other round) right before the setup's own: before and after, A B B A A B ... in one sitting.
    Returns {label: `stats` and "pieces", the medians of `pieces`}.
    """
    from playwright.sync_api import sync_playwright  # lazy: a test-only dependency

    sources = [("", None)] + ([(f" ({against.name})", str(against))] if against else [])
    with (
        tempfile.TemporaryDirectory(prefix="ekfslam-latency-") as tmp_name,
        contextlib.ExitStack() as stack,
    ):
        tmp, servers = Path(tmp_name), []
        for k, (_suffix, path) in enumerate(sources):
            folder = tmp / f"server{k}" / "notebooks"
            folder.mkdir(parents=True)
            for j, setup in enumerate(setups.values()):
                (folder / f"panel{j}.ipynb").write_text(json.dumps(panel_notebook(setup)))
            servers.append(
                stack.enter_context(voila_server(folder, folder.parent, pythonpath=path))
            )
        p = stack.enter_context(sync_playwright())
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        pages = {
            label + suffix: open_panel(browser, base, token, f"panel{j}")
            for j, label in enumerate(setups)
            for (suffix, _path), (base, token, _pid) in zip(sources, servers, strict=True)
        }
        results: dict[str, list[Move]] = {label: [] for label in pages}
        for r in range(rounds):
            n = moves // rounds + (r < moves % rounds)
            for label in setups:
                pair = [label + suffix for suffix, _path in sources]
                for name in pair if r % 2 == 0 else pair[::-1]:
                    results[name] += measure_moves(pages[name], n)
        split = {label: pieces(page) for label, page in pages.items()}
        for page in pages.values():
            page.close(run_before_unload=True)
        browser.close()
    return {label: {**stats(ms), "pieces": split[label]} for label, ms in results.items()}
