"""Tests for sswjax.data.download against a local HTTP server (no internet needed)."""

import hashlib
import http.server
import re
import socket
import struct
import threading
import time
import zipfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.data.datasets import load_middeval3
from sswjax.data.download import (
    MIDDEVAL3_ARCHIVES,
    DownloadError,
    download_file,
    download_middeval3,
    extract_zip,
    middeval3_urls,
)
from sswjax.data.io import InputError, write_pfm

# ----------------------------------------------------------------------------- local server


class _Handler(http.server.BaseHTTPRequestHandler):
    """Serves ``server.state.root``; supports ``Range: bytes=N-`` unless told to ignore it."""

    def do_GET(self):  # noqa: N802
        state = self.server.state
        range_header = self.headers.get("Range")
        state.requests.append((self.path, range_header))
        if state.delay:
            time.sleep(state.delay)
        path = state.root / self.path.split("?")[0].lstrip("/")
        if not path.is_file():
            self.send_error(404, "Not Found")
            return
        data = path.read_bytes()
        start = 0
        if range_header and not state.ignore_range:
            match = re.fullmatch(r"bytes=(\d+)-", range_header)
            assert match, range_header
            start = int(match[1])
            if start >= len(data):
                self.send_response(416)
                self.send_header("Content-Range", f"bytes */{len(data)}")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        else:
            self.send_response(200)
        body = data[start:]
        self.send_header("Content-Type", "application/octet-stream")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if state.truncate:  # one-shot: simulate a connection dropped halfway
            state.truncate = False
            body = body[: len(body) // 2]
        try:
            self.wfile.write(body)
        except OSError:
            pass  # client gave up (timeout test)

    def log_message(self, format, *args):  # noqa: A002
        pass


class _State:
    def __init__(self, root: Path):
        self.root = root
        self.url = ""
        self.ignore_range = False
        self.truncate = False
        self.delay = 0.0
        self.requests: list[tuple[str, str | None]] = []


@pytest.fixture
def server(tmp_path, monkeypatch):
    for name in ("no_proxy", "NO_PROXY"):
        monkeypatch.setenv(name, "*")
    root = tmp_path / "www"
    root.mkdir()
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    httpd.state = _State(root)
    httpd.state.url = f"http://127.0.0.1:{httpd.server_address[1]}/"
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.05})
    thread.daemon = True
    thread.start()
    yield httpd.state
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


# ----------------------------------------------------------------------------- fake archives

CALIB = "cam0=[100 0 5; 0 100 3; 0 0 1]\ncam1=[100 0 6; 0 100 3; 0 0 1]\ndoffs=1\nbaseline=190\nwidth=10\nheight=6\nndisp=16\nvmin=1\nvmax=14\n"
SHAPE = (6, 10)


def _png(array) -> bytes:
    return iio.imwrite("<bytes>", array, extension=".png")


def build_archives(folder: Path, tmp: Path, *, resolution="Q", compression=zipfile.ZIP_DEFLATED):
    """Write fake MiddEval3-data-R.zip and MiddEval3-GT0-R.zip; return the scene contents."""
    rng = np.random.default_rng(0)
    scenes = {}
    data_zip = folder / f"MiddEval3-data-{resolution}.zip"
    gt_zip = folder / f"MiddEval3-GT0-{resolution}.zip"
    with zipfile.ZipFile(data_zip, "w", compression) as zd, zipfile.ZipFile(
        gt_zip, "w", compression
    ) as zg:
        zd.writestr(zipfile.ZipInfo("MiddEval3/"), b"")  # a folder entry, like real archives
        for split, scene in [("training", "Scene1"), ("training", "Scene2"), ("test", "Scene3")]:
            base = f"MiddEval3/{split}{resolution}/{scene}/"
            left = rng.integers(0, 256, SHAPE + (3,), dtype=np.uint8)
            right = rng.integers(0, 256, SHAPE + (3,), dtype=np.uint8)
            zd.writestr(base + "im0.png", _png(left))
            zd.writestr(base + "im1.png", _png(right))
            zd.writestr(base + "calib.txt", CALIB)
            gt = mask = None
            if split == "training":
                gt = rng.uniform(0, 15, SHAPE).astype(np.float32)
                gt[0, 0] = np.inf
                write_pfm(tmp / "gt.pfm", gt)
                zg.write(tmp / "gt.pfm", base + "disp0GT.pfm")
                mask = np.full(SHAPE, 255, np.uint8)
                mask[:, :2] = 128
                zg.writestr(base + "mask0nocc.png", _png(mask))
            scenes[scene] = (left, right, gt, mask)
    return scenes


def flip_member_byte(archive: Path, member: str, *, first: bool = False) -> None:
    """Corrupt one byte of a member's stored data (sizes unchanged): the middle one, or the
    first one (for a deflated member that makes the stream itself invalid)."""
    with zipfile.ZipFile(archive) as zf:
        info = zf.getinfo(member)
    raw = bytearray(archive.read_bytes())
    name_len, extra_len = struct.unpack("<HH", raw[info.header_offset + 26 : info.header_offset + 30])
    start = info.header_offset + 30 + name_len + extra_len
    if first:
        raw[start] = 0xFF  # deflate block type 3: "invalid block type"
    else:
        raw[start + info.compress_size // 2] ^= 0xFF
    archive.write_bytes(bytes(raw))


@pytest.fixture
def payload(server):
    data = np.random.default_rng(1).integers(0, 256, 200_003, dtype=np.uint8).tobytes()
    (server.root / "blob.bin").write_bytes(data)
    return data


# ----------------------------------------------------------------------------- download_middeval3


def test_download_middeval3_layout_and_load(server, tmp_path):
    scenes = build_archives(server.root, tmp_path)
    dest = tmp_path / "data"
    root = download_middeval3(dest, base_url=server.url, progress=False)
    assert root == dest / "MiddEval3"
    for scene in ("Scene1", "Scene2"):
        for name in ("im0.png", "im1.png", "calib.txt", "disp0GT.pfm", "mask0nocc.png"):
            assert (root / "trainingQ" / scene / name).is_file()
    assert (root / "testQ" / "Scene3" / "im0.png").is_file()
    assert not list(dest.glob("*.zip")) and not list(dest.glob("*.part"))
    assert not list(dest.glob(".extract-*"))

    loaded = load_middeval3(root)
    assert [s.name for s in loaded] == ["Scene1", "Scene2"]
    for s in loaded:
        left, right, gt, mask = scenes[s.name]
        assert s.ndisp == 16
        np.testing.assert_array_equal(s.left, left)
        np.testing.assert_array_equal(s.right, right)
        np.testing.assert_array_equal(s.ground_truth, gt)
        np.testing.assert_array_equal(s.mask, mask)


def test_download_middeval3_is_idempotent_and_repairs(server, tmp_path):
    build_archives(server.root, tmp_path, resolution="H")
    dest = tmp_path / "data"
    root = download_middeval3(dest, resolution="H", base_url=server.url, progress=True,
                              keep_archives=True)  # fmt: skip
    assert len(server.requests) == 2
    assert sorted(p.name for p in dest.glob("*.zip")) == sorted(MIDDEVAL3_ARCHIVES["H"])

    assert download_middeval3(dest, resolution="H", base_url=server.url, progress=False,
                              keep_archives=True) == root  # fmt: skip
    assert len(server.requests) == 2  # nothing fetched again

    (root / "trainingH" / "Scene1" / "im0.png").unlink()
    download_middeval3(dest, resolution="H", base_url=server.url, progress=False)
    assert len(server.requests) == 2  # repaired from the kept archive
    assert (root / "trainingH" / "Scene1" / "im0.png").is_file()
    assert not list(dest.glob("*.zip"))  # archives removed now

    download_middeval3(dest, resolution="H", base_url=server.url, progress=False)
    assert len(server.requests) == 2
    assert len(load_middeval3(root, split="trainingH")) == 2


def test_download_middeval3_corrupt_archive_extracts_nothing(server, tmp_path):
    build_archives(server.root, tmp_path)
    flip_member_byte(server.root / "MiddEval3-data-Q.zip", "MiddEval3/trainingQ/Scene1/calib.txt")
    dest = tmp_path / "data"
    with pytest.raises(InputError, match=r"corrupt.*calib\.txt"):
        download_middeval3(dest, base_url=server.url, progress=False)
    assert not (dest / "MiddEval3").exists()
    assert not list(dest.glob(".extract-*"))
    # The archive passed the size check, so it stays; a rerun says what to do about it.
    with pytest.raises(InputError, match="delete it and run again"):
        download_middeval3(dest, base_url=server.url, progress=False)


def test_download_middeval3_checks_layout(server, tmp_path):
    for name in MIDDEVAL3_ARCHIVES["Q"]:
        with zipfile.ZipFile(server.root / name, "w") as zf:
            zf.writestr("Other/readme.txt", "not MiddEval3")
    with pytest.raises(InputError, match=r"did not produce .*trainingQ"):
        download_middeval3(tmp_path / "data", base_url=server.url, progress=False)


def test_middeval3_urls():
    assert middeval3_urls("F", base_url="http://h/zip/") == [
        "http://h/zip/MiddEval3-data-F.zip",
        "http://h/zip/MiddEval3-GT0-F.zip",
    ]
    assert middeval3_urls()[0].startswith("https://vision.middlebury.edu/stereo/submit3/zip/")
    with pytest.raises(ValueError, match="resolution must be one of Q, H, F"):
        middeval3_urls("X")
    with pytest.raises(ValueError, match="resolution"):
        download_middeval3("unused", resolution="q")


# ----------------------------------------------------------------------------- download_file


def test_download_file_full(server, payload, tmp_path):
    dest = tmp_path / "sub" / "blob.bin"
    sha = hashlib.sha256(payload).hexdigest()
    assert download_file(server.url + "blob.bin", dest, sha256=sha.upper(),
                         expected_size=len(payload), progress=False) == dest  # fmt: skip
    assert dest.read_bytes() == payload
    assert server.requests == [("/blob.bin", None)]
    assert not (tmp_path / "sub" / "blob.bin.part").exists()


def test_download_file_resumes_partial(server, payload, tmp_path):
    dest = tmp_path / "blob.bin"
    half = len(payload) // 2
    (tmp_path / "blob.bin.part").write_bytes(payload[:half])
    download_file(server.url + "blob.bin", dest, progress=False, chunk_size=4096,
                  sha256=hashlib.sha256(payload).hexdigest())  # fmt: skip
    assert server.requests == [("/blob.bin", f"bytes={half}-")]
    assert dest.read_bytes() == payload
    assert not (tmp_path / "blob.bin.part").exists()


def test_download_file_server_ignoring_range_restarts(server, payload, tmp_path):
    server.ignore_range = True
    dest = tmp_path / "blob.bin"
    (tmp_path / "blob.bin.part").write_bytes(b"x" * 1000)  # stale: must be discarded
    download_file(server.url + "blob.bin", dest, progress=False)
    assert server.requests == [("/blob.bin", "bytes=1000-")]
    assert dest.read_bytes() == payload


def test_download_file_complete_part_gets_416(server, payload, tmp_path):
    dest = tmp_path / "blob.bin"
    (tmp_path / "blob.bin.part").write_bytes(payload)
    download_file(server.url + "blob.bin", dest, progress=False,
                  sha256=hashlib.sha256(payload).hexdigest())  # fmt: skip
    assert server.requests == [("/blob.bin", f"bytes={len(payload)}-")]
    assert dest.read_bytes() == payload


def test_download_file_too_long_part_restarts(server, payload, tmp_path):
    dest = tmp_path / "blob.bin"
    (tmp_path / "blob.bin.part").write_bytes(payload + b"extra")
    download_file(server.url + "blob.bin", dest, progress=False)
    assert server.requests[-1] == ("/blob.bin", None)
    assert dest.read_bytes() == payload


def test_download_file_truncated_keeps_part_then_resumes(server, payload, tmp_path):
    server.truncate = True
    dest = tmp_path / "blob.bin"
    part = tmp_path / "blob.bin.part"
    with pytest.raises(DownloadError, match="incomplete.*run again to resume") as info:
        download_file(server.url + "blob.bin", dest, progress=False)
    assert "\n" not in str(info.value) and server.url + "blob.bin" in str(info.value)
    assert not dest.exists()
    assert part.read_bytes() == payload[: len(payload) // 2]

    download_file(server.url + "blob.bin", dest, progress=False)
    assert server.requests[-1] == ("/blob.bin", f"bytes={len(payload) // 2}-")
    assert dest.read_bytes() == payload
    assert not part.exists()


def test_download_file_sha256_mismatch(server, payload, tmp_path):
    dest = tmp_path / "blob.bin"
    with pytest.raises(DownloadError, match="checksum mismatch") as info:
        download_file(server.url + "blob.bin", dest, sha256="0" * 64, progress=False)
    assert "\n" not in str(info.value)
    assert not dest.exists() and not (tmp_path / "blob.bin.part").exists()


def test_download_file_size_mismatch(server, payload, tmp_path):
    dest = tmp_path / "blob.bin"
    (tmp_path / "blob.bin.part").write_bytes(payload[:10])
    with pytest.raises(DownloadError, match=f"size mismatch.*{len(payload)} bytes"):
        download_file(server.url + "blob.bin", dest, expected_size=len(payload) + 1,
                      progress=False)  # fmt: skip
    assert not dest.exists() and not (tmp_path / "blob.bin.part").exists()


def test_download_file_404_is_one_line(server, tmp_path):
    url = server.url + "missing.zip"
    with pytest.raises(DownloadError) as info:
        download_file(url, tmp_path / "missing.zip", progress=False)
    message = str(info.value)
    assert "\n" not in message and url in message and "404" in message
    assert isinstance(info.value, InputError)
    assert list(tmp_path.iterdir()) == [server.root]


def test_download_file_timeout(server, payload, tmp_path):
    server.delay = 0.5
    with pytest.raises(DownloadError, match="timed out") as info:
        download_file(server.url + "blob.bin", tmp_path / "b", progress=False, timeout=0.1)
    assert server.url in str(info.value) and "\n" not in str(info.value)


def test_download_file_connection_refused(tmp_path, monkeypatch):
    for name in ("no_proxy", "NO_PROXY"):
        monkeypatch.setenv(name, "*")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/x.zip"
    with pytest.raises(DownloadError, match=rf"cannot download {re.escape(url)}: ") as info:
        download_file(url, tmp_path / "x.zip", progress=False, timeout=5)
    assert "\n" not in str(info.value)


def test_download_file_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="sha256"):
        download_file("http://127.0.0.1/x", tmp_path / "x", sha256="abc")
    with pytest.raises(ValueError, match="expected_size"):
        download_file("http://127.0.0.1/x", tmp_path / "x", expected_size=-1)
    with pytest.raises(DownloadError, match="cannot download not-a-url"):
        download_file("not-a-url", tmp_path / "x", progress=False)


# ----------------------------------------------------------------------------- extract_zip


@pytest.mark.parametrize(
    "compression, first",
    [(zipfile.ZIP_STORED, False), (zipfile.ZIP_DEFLATED, False), (zipfile.ZIP_DEFLATED, True)],
)
def test_extract_zip_corrupt_writes_nothing(tmp_path, compression, first):
    build_archives(tmp_path, tmp_path, compression=compression)
    archive = tmp_path / "MiddEval3-data-Q.zip"
    flip_member_byte(archive, "MiddEval3/trainingQ/Scene2/calib.txt", first=first)
    out = tmp_path / "out"
    with pytest.raises(InputError, match=rf"{re.escape(str(archive))} is corrupt") as info:
        extract_zip(archive, out)
    assert "\n" not in str(info.value)
    assert not out.exists()


@pytest.mark.parametrize(
    "member", ["../evil.txt", "MiddEval3/../../evil.txt", "/tmp/evil.txt", "C:/evil.txt",
               "a\\..\\..\\evil.txt"]  # fmt: skip
)
def test_extract_zip_refuses_zip_slip(tmp_path, member):
    archive = tmp_path / "evil.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("MiddEval3/ok.txt", "fine")
        zf.writestr(member, "evil")
    out = tmp_path / "a" / "b"
    with pytest.raises(InputError, match="unsafe member name"):
        extract_zip(archive, out)
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["evil.zip"]


def test_extract_zip_not_a_zip(tmp_path):
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"this is not a zip file" * 10)
    with pytest.raises(InputError, match="not a valid zip"):
        extract_zip(bad, tmp_path / "out")
    with pytest.raises(InputError, match="archive not found"):
        extract_zip(tmp_path / "nope.zip", tmp_path / "out")


def test_extract_zip_returns_files_and_overwrites(tmp_path):
    archive = tmp_path / "a.zip"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(zipfile.ZipInfo("top/"), b"")
        zf.writestr(zipfile.ZipInfo("top/empty/"), b"")
        zf.writestr("top/x/one.txt", "1")
        zf.writestr("top/two.txt", "2")
    out = tmp_path / "out"
    (out / "top").mkdir(parents=True)
    (out / "top" / "two.txt").write_text("old")
    (out / "top" / "keep.txt").write_text("untouched")
    files = extract_zip(archive, out)
    assert files == [out / "top" / "x" / "one.txt", out / "top" / "two.txt"]
    assert (out / "top" / "two.txt").read_text() == "2"
    assert (out / "top" / "keep.txt").read_text() == "untouched"
    assert (out / "top" / "empty").is_dir()
    assert sorted(p.name for p in out.iterdir()) == ["top"]  # temporary folder removed
