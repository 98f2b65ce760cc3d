"""fetch_mrclam against a real HTTP server on 127.0.0.1 serving archives built from Dataset 7.

The archives hold the first 1,000 lines of each Dataset 7 file: the fetcher only checks file
names, and the truncated files still load, which keeps building them fast.
"""

from __future__ import annotations

import functools
import http.server
import io
import socket
import threading
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from ekfslam.logs.mrclam.cache import EXPECTED_FILES, default_cache_dir
from ekfslam.logs.mrclam.fetch import FetchError, fetch_mrclam
from ekfslam.logs.mrclam.load import load_mrclam

pytestmark = pytest.mark.shared_data


def truncated(path: Path, lines: int = 1000) -> bytes:
    """The first `lines` lines; a robot's measurements end with its odometry's first lines (the
    loader refuses measurements beyond the odometry: files on different clocks)."""
    kept = path.read_bytes().split(b"\r\n")[:lines]
    if path.name.endswith("_Measurement.dat"):
        odometry = path.with_name(path.name.replace("Measurement", "Odometry"))
        end = float(odometry.read_bytes().split(b"\r\n")[lines - 1].split()[0])
        kept = [ln for ln in kept if ln.startswith(b"#") or float(ln.split()[0]) <= end]
    return b"\r\n".join(kept) + b"\r\n"


def write_zip(path: Path, members: dict[str, bytes]) -> None:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)


@pytest.fixture(scope="session")
def files(mrclam7: Path) -> dict[str, bytes]:
    return {name: truncated(mrclam7 / name) for name in EXPECTED_FILES}


@pytest.fixture(scope="session")
def served(tmp_path_factory: pytest.TempPathFactory, files: dict[str, bytes]) -> Path:
    root = tmp_path_factory.mktemp("served")
    write_zip(root / "MRCLAM7.zip", {f"MRCLAM_Dataset7/{n}": d for n, d in files.items()})
    write_zip(root / "MRCLAM2.zip", files)  # files at the top level
    write_zip(  # dataset 4's folder has another name; macOS zips add resource-fork shadows
        root / "MRCLAM4.zip",
        {
            **{f"MRSLAM_Dataset4/{n}": d for n, d in files.items()},
            "__MACOSX/MRSLAM_Dataset4/._Barcodes.dat": b"junk",
        },
    )
    incomplete = {n: d for n, d in files.items() if n != "Robot3_Measurement.dat"}
    write_zip(root / "MRCLAM5.zip", {f"MRCLAM_Dataset5/{n}": d for n, d in incomplete.items()})
    write_zip(root / "MRCLAM6.zip", {**files, "../escaped.dat": b"outside"})
    write_zip(root / "MRCLAM1.zip", {**files, "/tmp/absolute.dat": b"outside"})
    (root / "MRCLAM8.zip").write_bytes(b"<html>this is not a zip</html>")
    return root


class Server(http.server.ThreadingHTTPServer):
    requests: list[str]
    url: str


class Handler(http.server.SimpleHTTPRequestHandler):
    """Serves files; /short/* promises more bytes than it sends; /nolength/* sends no length."""

    server: Server

    def log_message(self, *args) -> None:
        pass

    def do_GET(self) -> None:
        self.server.requests.append(self.path)
        if self.path.startswith("/short/"):
            self.send_response(200)
            self.send_header("Content-Length", "100000")
            self.end_headers()
            self.wfile.write(b"PK" + bytes(998))
            return
        if self.path.startswith("/nolength/"):
            data = (Path(self.directory) / self.path.removeprefix("/nolength/")).read_bytes()
            self.send_response(200)
            self.end_headers()
            self.wfile.write(data)  # HTTP/1.0: the body ends when the connection closes
            return
        super().do_GET()


@pytest.fixture(scope="module")
def server(served: Path) -> Iterator[Server]:
    httpd = Server(("127.0.0.1", 0), functools.partial(Handler, directory=str(served)))
    httpd.requests = []
    httpd.url = f"http://127.0.0.1:{httpd.server_address[1]}/"
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield httpd
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    for name in ("EKFSLAM_CACHE", "EKFSLAM_MRCLAM_URL", "XDG_CACHE_HOME"):
        monkeypatch.delenv(name, raising=False)
    return tmp_path / "cache"


def leftovers(cache: Path) -> list[str]:
    folder = cache / "mrclam"
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


def test_fetch_downloads_once_then_uses_the_cache(server: Server, cache: Path, files) -> None:
    bar = io.StringIO()
    before = len(server.requests)
    path = fetch_mrclam(7, cache_dir=cache, base_url=server.url, stream=bar)
    assert path == cache / "mrclam" / "MRCLAM_Dataset7"
    assert sorted(p.name for p in path.iterdir()) == sorted(EXPECTED_FILES)
    assert (path / "Robot5_Odometry.dat").read_bytes() == files["Robot5_Odometry.dat"]
    assert server.requests[before:] == ["/MRCLAM7.zip"]
    assert leftovers(cache) == ["MRCLAM_Dataset7"]  # no .part file, no staging folder
    assert "MRCLAM7.zip [" in bar.getvalue() and "100%" in bar.getvalue()

    again = fetch_mrclam(7, cache_dir=cache, base_url=server.url, stream=bar)
    assert again == path
    assert len(server.requests) == before + 1

    run, report = load_mrclam(path, 2)
    assert run.meta.name == "mrclam7-robot2"
    assert report.odometry_rows == 996


def test_a_damaged_cache_is_fetched_again(server: Server, cache: Path) -> None:
    path = fetch_mrclam(7, cache_dir=cache, base_url=server.url, progress=False)
    (path / "Robot3_Groundtruth.dat").unlink()
    (path / "stray.txt").write_text("replaced with the folder")
    before = len(server.requests)
    assert fetch_mrclam(7, cache_dir=cache, base_url=server.url, progress=False) == path
    assert len(server.requests) == before + 1
    assert (path / "Robot3_Groundtruth.dat").is_file()
    assert not (path / "stray.txt").exists()
    assert leftovers(cache) == ["MRCLAM_Dataset7"]


@pytest.mark.parametrize("n", [2, 4])
def test_other_archive_layouts(server: Server, cache: Path, n: int) -> None:
    path = fetch_mrclam(n, cache_dir=cache, base_url=server.url, progress=False)
    assert path.name == f"MRCLAM_Dataset{n}"
    assert sorted(p.name for p in path.iterdir()) == sorted(EXPECTED_FILES)
    assert leftovers(cache) == [f"MRCLAM_Dataset{n}"]


def test_http_404_is_one_clear_line(server: Server, cache: Path) -> None:
    with pytest.raises(FetchError) as caught:
        fetch_mrclam(3, cache_dir=cache, base_url=server.url, progress=False)
    message = str(caught.value)
    assert message.startswith(f"could not download {server.url}MRCLAM3.zip: HTTP 404")
    assert "EKFSLAM_MRCLAM_URL" in message
    assert str(cache / "mrclam" / "MRCLAM_Dataset3") in message
    assert "\n" not in message
    assert leftovers(cache) == []


def test_truncated_download_is_an_error_and_removed(server: Server, cache: Path) -> None:
    with pytest.raises(FetchError, match="connection closed after 1000 of 100000 bytes"):
        fetch_mrclam(9, cache_dir=cache, base_url=server.url + "short/", progress=False)
    assert leftovers(cache) == []


def test_unreachable_server(cache: Path) -> None:
    with socket.socket() as sock:  # a port that nothing listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    with pytest.raises(FetchError, match=r"could not download .*refused"):
        fetch_mrclam(7, cache_dir=cache, base_url=f"http://127.0.0.1:{port}/", progress=False)
    assert leftovers(cache) == []


def test_zip_missing_a_file(server: Server, cache: Path) -> None:
    with pytest.raises(FetchError, match=r"missing Robot3_Measurement\.dat$"):
        fetch_mrclam(5, cache_dir=cache, base_url=server.url, progress=False)
    assert leftovers(cache) == []


@pytest.mark.parametrize(("n", "member"), [(6, "../escaped.dat"), (1, "/tmp/absolute.dat")])
def test_path_traversal_is_refused(server: Server, cache: Path, n: int, member: str) -> None:
    with pytest.raises(FetchError, match=f"unsafe file name '{member}'"):
        fetch_mrclam(n, cache_dir=cache, base_url=server.url, progress=False)
    assert leftovers(cache) == []
    assert not (cache / "escaped.dat").exists()
    assert not (cache.parent / "escaped.dat").exists()


def test_not_a_zip(server: Server, cache: Path) -> None:
    with pytest.raises(FetchError, match=r"MRCLAM8\.zip is not a zip archive"):
        fetch_mrclam(8, cache_dir=cache, base_url=server.url, progress=False)
    assert leftovers(cache) == []


def test_progress_without_content_length(server: Server, cache: Path) -> None:
    bar = io.StringIO()
    fetch_mrclam(7, cache_dir=cache, base_url=server.url + "nolength/", stream=bar)
    assert bar.getvalue().startswith("\rMRCLAM7.zip 0.")
    assert "%" not in bar.getvalue() and bar.getvalue().endswith(" MB\n")


def test_no_progress_means_no_output(server: Server, cache: Path) -> None:
    bar = io.StringIO()
    fetch_mrclam(7, cache_dir=cache, base_url=server.url, progress=False, stream=bar)
    assert bar.getvalue() == ""


def test_environment_variables(server: Server, cache: Path, monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("EKFSLAM_MRCLAM_URL", server.url)
    monkeypatch.setenv("EKFSLAM_CACHE", str(cache))
    assert fetch_mrclam(7, progress=False) == cache / "mrclam" / "MRCLAM_Dataset7"

    monkeypatch.delenv("EKFSLAM_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "ekfslam"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "ekfslam"


@pytest.mark.parametrize("n", [0, 10, True, "7"])
def test_dataset_number_must_be_1_to_9(cache: Path, n) -> None:
    with pytest.raises(FetchError, match="numbered 1 to 9"):
        fetch_mrclam(n, cache_dir=cache)


def test_help_and_readme_name_the_cache_the_code_uses(monkeypatch, tmp_path: Path) -> None:
    """Regression: --help said ~/.cache, the README ~/.cache/ekfslam (now the MRCLAM guide)."""
    import argparse

    from ekfslam.cli import fetch as fetch_command
    from ekfslam.logs.mrclam.cache import CACHE_DEFAULT_HELP

    parser = argparse.ArgumentParser()
    fetch_command.add_command(parser.add_subparsers(), "fetch", "download")
    fetch = next(a for a in parser._subparsers._group_actions[0].choices.values())
    cache_help = next(a.help for a in fetch._actions if "--cache" in a.option_strings)
    assert cache_help == f"cache folder (default: {CACHE_DEFAULT_HELP})"
    guide = (Path(__file__).resolve().parents[2] / "docs" / "guide" / "mrclam.md").read_text()
    assert CACHE_DEFAULT_HELP in " ".join(guide.replace("`", "").split())
    # ... and that is what the code does, in that order
    monkeypatch.delenv("EKFSLAM_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "ekfslam"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_cache_dir() == tmp_path / "home" / ".cache" / "ekfslam"
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"
