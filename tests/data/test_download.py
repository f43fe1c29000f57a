"""Tests for sswjax.data.download: what is ours on top of pooch (resume, sizes, errors, safe
extraction), against a local HTTP server serving small fake archives (no internet needed)."""

import functools
import hashlib
import http.server
import re
import socket
import struct
import threading
import zipfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax import cli
from sswjax.data import download
from sswjax.data.download import DownloadError, ResumingDownloader, download_middeval3
from sswjax.data.io import InputError, write_pfm
from sswjax.data.layouts import detect_layout, load_scenes

# ----------------------------------------------------------------------------- local server


class _Handler(http.server.BaseHTTPRequestHandler):
    """Serves ``server.state.root``, honouring ``Range: bytes=N-`` unless told to ignore it."""

    def do_GET(self):  # noqa: N802
        state = self.server.state
        range_header = self.headers.get("Range")
        state.requests.append((self.path, range_header))
        path = state.root / self.path.lstrip("/")
        if not path.is_file():
            self.send_error(404, "Not Found")
            return
        data = path.read_bytes()
        start = int(re.fullmatch(r"bytes=(\d+)-", range_header)[1]) if range_header else 0
        if state.ignore_range or not range_header:
            start = 0
            self.send_response(200)
        elif start >= len(data):
            self.send_response(416)
            self.send_header("Content-Range", f"bytes */{len(data)}")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        else:
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        body = data[start:]
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if state.truncate:  # one-shot: a connection dropped halfway
            state.truncate, body = False, body[: len(body) // 2]
        self.wfile.write(body)

    def log_message(self, format, *args):  # noqa: A002
        pass


class _State:
    def __init__(self, root: Path, url: str):
        self.root, self.url = root, url
        self.ignore_range = self.truncate = False
        self.requests: list[tuple[str, str | None]] = []


@pytest.fixture
def server(tmp_path, monkeypatch):
    for name in ("no_proxy", "NO_PROXY"):
        monkeypatch.setenv(name, "*")
    (tmp_path / "www").mkdir()
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    httpd.state = _State(tmp_path / "www", f"http://127.0.0.1:{httpd.server_address[1]}/")
    thread = threading.Thread(target=httpd.serve_forever, kwargs={"poll_interval": 0.05})
    thread.start()
    yield httpd.state
    httpd.shutdown()
    httpd.server_close()
    thread.join(timeout=5)


@pytest.fixture
def payload(server):
    data = np.random.default_rng(1).integers(0, 256, 200_003, dtype=np.uint8).tobytes()
    (server.root / "blob.bin").write_bytes(data)
    return data


def _closed_port_url() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"http://127.0.0.1:{s.getsockname()[1]}/"


# ----------------------------------------------------------------------------- fake archives

CALIB = "cam0=[100 0 5; 0 100 3; 0 0 1]\ncam1=[100 0 6; 0 100 3; 0 0 1]\ndoffs=1\nbaseline=190\nwidth=10\nheight=6\nndisp=16\nvmin=1\nvmax=14\n"
SHAPE = (6, 10)


def _png(array) -> bytes:
    return iio.imwrite("<bytes>", array, extension=".png")


def build_archives(folder: Path, tmp: Path, *, resolution="Q", compression=zipfile.ZIP_DEFLATED):
    """Write fake MiddEval3-data-R.zip and MiddEval3-GT0-R.zip; return the scene contents."""
    rng = np.random.default_rng(0)
    scenes = {}
    with zipfile.ZipFile(folder / f"MiddEval3-data-{resolution}.zip", "w", compression) as zd, \
            zipfile.ZipFile(folder / f"MiddEval3-GT0-{resolution}.zip", "w", compression) as zg:  # fmt: skip
        zd.writestr(zipfile.ZipInfo("MiddEval3/"), b"")  # a folder entry, like real archives
        for split, scene in [("training", "Scene1"), ("training", "Scene2"), ("test", "Scene3")]:
            base = f"MiddEval3/{split}{resolution}/{scene}/"
            left, right = rng.integers(0, 256, (2, *SHAPE, 3), dtype=np.uint8)
            zd.writestr(base + "im0.png", _png(left))
            zd.writestr(base + "im1.png", _png(right))
            zd.writestr(base + "calib.txt", CALIB)
            gt = mask = None
            if split == "training":
                gt = rng.uniform(0, 15, SHAPE).astype(np.float32)
                write_pfm(tmp / "gt.pfm", gt)
                zg.write(tmp / "gt.pfm", base + "disp0GT.pfm")
                mask = np.full(SHAPE, 255, np.uint8)
                zg.writestr(base + "mask0nocc.png", _png(mask))
            scenes[scene] = (left, right, gt, mask)
    return scenes


def flip_member_byte(archive: Path, member: str, *, first: bool = False) -> None:
    """Corrupt one stored byte of a member (sizes unchanged): its middle one, or its first one
    (for a deflated member, that makes the stream itself invalid)."""
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


# ----------------------------------------------------------------------------- ResumingDownloader


def test_resumes_a_partial_download_with_range(server, payload, tmp_path):
    part, out = tmp_path / "blob.bin.part", tmp_path / "blob.bin"
    part.write_bytes(payload[:1000])
    ResumingDownloader(part, expected_size=len(payload), progress=False)(
        server.url + "blob.bin", out, None)  # fmt: skip
    assert server.requests == [("/blob.bin", "bytes=1000-")]
    assert out.read_bytes() == payload and not part.exists()


def test_server_ignoring_range_gets_a_full_download(server, payload, tmp_path):
    server.ignore_range = True
    part, out = tmp_path / "blob.bin.part", tmp_path / "blob.bin"
    part.write_bytes(b"x" * 1000)  # stale: must be overwritten, not appended to
    ResumingDownloader(part, progress=True)(server.url + "blob.bin", out, None)
    assert server.requests == [("/blob.bin", "bytes=1000-")]
    assert out.read_bytes() == payload


def test_part_longer_than_the_file_restarts_after_416(server, payload, tmp_path):
    part, out = tmp_path / "blob.bin.part", tmp_path / "blob.bin"
    part.write_bytes(payload + b"extra")
    ResumingDownloader(part, progress=False)(server.url + "blob.bin", out, None)
    assert [r for _, r in server.requests] == [f"bytes={len(payload) + 5}-", None]
    assert out.read_bytes() == payload


def test_interrupted_transfer_keeps_the_part_then_resumes(server, payload, tmp_path):
    server.truncate = True
    part, out = tmp_path / "blob.bin.part", tmp_path / "blob.bin"
    url = server.url + "blob.bin"
    with pytest.raises(DownloadError, match="incomplete.*run again to resume") as info:
        ResumingDownloader(part, progress=False)(url, out, None)
    assert "\n" not in str(info.value) and url in str(info.value)
    assert part.read_bytes() == payload[: len(payload) // 2] and not out.exists()
    ResumingDownloader(part, progress=False)(url, out, None)
    assert server.requests[-1] == ("/blob.bin", f"bytes={len(payload) // 2}-")
    assert out.read_bytes() == payload and not part.exists()


def test_size_mismatch_deletes_the_part(server, payload, tmp_path):
    part, out = tmp_path / "blob.bin.part", tmp_path / "blob.bin"
    part.write_bytes(payload[:10])
    with pytest.raises(DownloadError, match=rf"size mismatch.*{len(payload)} bytes, expected 7;"):
        ResumingDownloader(part, expected_size=7, progress=False)(server.url + "blob.bin", out)
    assert not part.exists() and not out.exists()


@pytest.mark.parametrize("where", ["closed port", "404"])
def test_unreachable_or_missing_is_one_line(server, tmp_path, where):
    url = (_closed_port_url() if where == "closed port" else server.url) + "missing.zip"
    with pytest.raises(DownloadError, match=rf"^cannot download {re.escape(url)}: \S") as info:
        ResumingDownloader(tmp_path / "x.part", timeout=5)(url, tmp_path / "x")
    assert "\n" not in str(info.value) and isinstance(info.value, InputError)
    reason = str(info.value).removeprefix(f"cannot download {url}: ")  # the port may hold "404"
    assert ("404" in reason) == (where == "404")
    assert not (tmp_path / "x.part").exists() and not (tmp_path / "x").exists()


# ----------------------------------------------------------------------------- extraction


@pytest.mark.parametrize("compression, first",
                         [(zipfile.ZIP_STORED, False), (zipfile.ZIP_DEFLATED, True)])  # fmt: skip
def test_corrupt_archive_extracts_nothing(tmp_path, compression, first):
    build_archives(tmp_path, tmp_path, compression=compression)
    archive = tmp_path / "MiddEval3-data-Q.zip"
    flip_member_byte(archive, "MiddEval3/trainingQ/Scene2/calib.txt", first=first)
    with pytest.raises(InputError, match=rf"{re.escape(str(archive))} is corrupt") as info:
        download._extract_zip(archive, tmp_path / "out")
    assert "\n" not in str(info.value) and not (tmp_path / "out").exists()


@pytest.mark.parametrize("member", ["../evil.txt", "MiddEval3/../../evil.txt", "/tmp/evil.txt",
                                    "C:/evil.txt", "a\\..\\..\\evil.txt"])  # fmt: skip
def test_unsafe_member_names_are_refused(tmp_path, member):
    archive = tmp_path / "evil.zip"
    with zipfile.ZipFile(archive, "w") as zf:
        zf.writestr("MiddEval3/ok.txt", "fine")
        zf.writestr(member, "evil")
    with pytest.raises(InputError, match="unsafe member name"):
        download._extract_zip(archive, tmp_path / "a" / "b")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["evil.zip"]


def test_extraction_moves_files_into_place(tmp_path):
    archive, out = tmp_path / "a.zip", tmp_path / "out"
    with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(zipfile.ZipInfo("top/"), b"")
        zf.writestr("top/x/one.txt", "1")
        zf.writestr("top/two.txt", "2")
    (out / "top").mkdir(parents=True)
    (out / "top" / "two.txt").write_text("old")
    (out / "top" / "keep.txt").write_text("untouched")
    assert download._extract_zip(archive, out) == [out / "top/x/one.txt", out / "top/two.txt"]
    assert (out / "top/two.txt").read_text() == "2"
    assert (out / "top/keep.txt").read_text() == "untouched"
    assert sorted(p.name for p in out.iterdir()) == ["top"]  # temporary folder removed


# ----------------------------------------------------------------------------- download_middeval3


def test_download_middeval3_end_to_end(server, tmp_path):
    scenes = build_archives(server.root, tmp_path, resolution="H")
    dest = tmp_path / "data"
    get = functools.partial(download_middeval3, dest, resolution="H", base_url=server.url,
                            progress=False)  # fmt: skip
    root = get(keep_archives=True)
    assert root == dest / "MiddEval3" and len(server.requests) == 2
    assert (root / "testH/Scene3/im0.png").is_file()
    loaded = load_scenes(root, split="trainingH")
    assert [s.name for s in loaded] == ["Scene1", "Scene2"]
    for s in loaded:
        left, right, gt, mask = scenes[s.name]
        assert s.ndisp == 16
        for got, want in [(s.left, left), (s.right, right), (s.ground_truth, gt), (s.mask, mask)]:
            np.testing.assert_array_equal(got, want)

    assert get(keep_archives=True) == root and len(server.requests) == 2  # nothing fetched
    (root / "trainingH/Scene1/im0.png").unlink()
    get()  # repaired from the kept archive (pooch finds it), which is then deleted
    assert len(server.requests) == 2 and (root / "trainingH/Scene1/im0.png").is_file()
    assert not list(dest.glob("*.zip")) and not list(dest.glob("*.part"))
    assert not list(dest.glob("tmp*")) and not list(dest.glob(".extract-*"))
    get()
    assert len(server.requests) == 2


def test_download_middeval3_checks_the_registry(server, tmp_path, monkeypatch):
    build_archives(server.root, tmp_path)
    data, gt = (server.root / name for name in download.MIDDEVAL3_ARCHIVES["Q"])
    sha = "sha256:" + hashlib.sha256(data.read_bytes()).hexdigest()
    monkeypatch.setitem(download.MIDDEVAL3_REGISTRY, data.name, (data.stat().st_size, sha))
    monkeypatch.setitem(download.MIDDEVAL3_REGISTRY, gt.name, (gt.stat().st_size + 1, None))
    with pytest.raises(DownloadError, match=rf"size mismatch for {re.escape(server.url)}.*GT0"):
        download_middeval3(tmp_path / "a", base_url=server.url, progress=False)
    assert (tmp_path / "a/MiddEval3/trainingQ/Scene1/im0.png").is_file()  # data was right

    monkeypatch.setitem(download.MIDDEVAL3_REGISTRY, data.name, (None, "sha256:" + "0" * 64))
    with pytest.raises(DownloadError, match="checksum mismatch for .*data-Q") as info:
        download_middeval3(tmp_path / "b", base_url=server.url, progress=False)
    assert "\n" not in str(info.value) and not list((tmp_path / "b").glob("*.zip"))


def test_download_middeval3_bad_archives(server, tmp_path):
    build_archives(server.root, tmp_path)
    flip_member_byte(server.root / "MiddEval3-data-Q.zip", "MiddEval3/trainingQ/Scene1/calib.txt")
    dest = tmp_path / "data"
    with pytest.raises(InputError, match=r"corrupt.*calib\.txt.*archive deleted, run again"):
        download_middeval3(dest, base_url=server.url, progress=False)
    assert not (dest / "MiddEval3").exists() and not list(dest.glob("*.zip"))

    for name in download.MIDDEVAL3_ARCHIVES["Q"]:
        with zipfile.ZipFile(server.root / name, "w") as zf:
            zf.writestr("Other/readme.txt", "not MiddEval3")
    with pytest.raises(InputError, match=r"did not produce .*trainingQ"):
        download_middeval3(tmp_path / "other", base_url=server.url, progress=False)


def test_middeval3_urls():
    assert download.middeval3_urls(resolution="F", base_url="http://h/zip") == [
        "http://h/zip/MiddEval3-data-F.zip", "http://h/zip/MiddEval3-GT0-F.zip"]  # fmt: skip
    assert download.middeval3_urls()[0] == download.DEFAULT_BASE_URL + "MiddEval3-data-Q.zip"
    with pytest.raises(ValueError, match="resolution must be one of Q, H, F"):
        download_middeval3("unused", resolution="q")


def test_cli_download(server, tmp_path, monkeypatch, capsys):
    build_archives(server.root, tmp_path)
    real = download.download_middeval3
    for base_url, status in [(server.url, 0), (_closed_port_url(), 2)]:
        monkeypatch.setattr(download, "download_middeval3",
                            functools.partial(real, base_url=base_url, progress=False))  # fmt: skip
        dest = tmp_path / f"data{status}"
        assert cli.main(["--no-cache", "download", "middlebury", "--dest", str(dest)]) == status
    out, err = capsys.readouterr()
    assert f"ready in {tmp_path / 'data0' / 'MiddEval3'}" in out
    errors = [line for line in err.splitlines() if line.startswith("sswjax:")]
    assert len(errors) == 1 and re.fullmatch(r"sswjax: error: cannot download http://127\.0\.0\.1:"
                                             r"\d+/MiddEval3-data-Q\.zip: .+", errors[0])  # fmt: skip


# ----------------------------------------------------------------------------- ETH3D, KITTI


def build_eth3d_archives(folder: Path, tmp: Path) -> None:
    """Fake two_view_training.7z (scene folders at its top) and two_view_training_gt.7z (in a
    top folder of its name): both packings unpack to ETH3D's layout."""
    py7zr = pytest.importorskip("py7zr")
    rng = np.random.default_rng(1)
    images, truth = tmp / "eth-images", tmp / "eth-gt"
    for scene in ("delivery_area_1l", "playground_2l"):
        (images / scene).mkdir(parents=True)
        (truth / scene).mkdir(parents=True)
        for name in ("im0.png", "im1.png"):
            iio.imwrite(images / scene / name, rng.integers(0, 256, SHAPE, dtype=np.uint8))
        (images / scene / "calib.txt").write_text(CALIB)
        write_pfm(truth / scene / "disp0GT.pfm", rng.uniform(0, 15, SHAPE).astype(np.float32))
        iio.imwrite(truth / scene / "mask0nocc.png", np.full(SHAPE, 255, np.uint8))
    for archive, source in (("two_view_training.7z", images), ("two_view_training_gt.7z", truth)):
        with py7zr.SevenZipFile(folder / archive, "w") as sz:
            top = "two_view_training_gt/" if archive.endswith("_gt.7z") else ""
            for scene in sorted(p.name for p in source.iterdir()):
                sz.writeall(source / scene, top + scene)


def test_download_eth3d_end_to_end(server, tmp_path):
    build_eth3d_archives(server.root, tmp_path)
    root = download.download_eth3d(tmp_path / "data", base_url=server.url, progress=False)
    assert root == tmp_path / "data" / "ETH3D" and len(server.requests) == 2
    assert detect_layout(root).name == "ETH3D"
    scenes = load_scenes(root)
    assert [s.name for s in scenes] == ["delivery_area_1l", "playground_2l"]
    # calib.txt's ndisp (16) is not below the width (10): ETH3D's convention, no search range;
    # the ground-truth rule sizes it instead, capped at the width - 1
    assert all(s.ndisp == 9 and s.mask is not None and s.left.shape == SHAPE for s in scenes)
    assert not list(root.glob("*.7z")) and not list(root.glob(".extract-*"))
    download.download_eth3d(tmp_path / "data", base_url=server.url, progress=False)
    assert len(server.requests) == 2  # everything in place: nothing fetched


def test_download_eth3d_without_py7zr_says_so(tmp_path, monkeypatch):
    monkeypatch.setitem(__import__("sys").modules, "py7zr", None)
    with pytest.raises(InputError, match=r"ETH3D's archives are 7z: install py7zr first"):
        download.download_eth3d(tmp_path, base_url="http://127.0.0.1:9/")
    assert not (tmp_path / "ETH3D").exists() or not any((tmp_path / "ETH3D").iterdir())


def test_cli_download_kitti_and_eth3d(server, tmp_path, monkeypatch, capsys):
    assert cli.main(["--no-cache", "download", "kitti", "--dest", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "KITTI needs a registration at https://www.cvlibs.net" in err
    assert f"{tmp_path / 'd'}/KITTI2012/training/image_0" in err and not (tmp_path / "d").exists()
    real = download.download_eth3d
    monkeypatch.setattr(download, "download_eth3d",
                        functools.partial(real, base_url=_closed_port_url(), progress=False))
    assert cli.main(["--no-cache", "download", "eth3d", "--dest", str(tmp_path / "e")]) == 2
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert re.fullmatch(r"sswjax: error: cannot download http://127\.0\.0\.1:\d+/"
                        r"two_view_training\.7z: .+", line)
