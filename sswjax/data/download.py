"""Downloading stereo data from the official sites, with pooch: MiddEval3 and ETH3D two-view.

:func:`download_middeval3` unpacks the archives of one resolution ``R`` (``Q``, ``H``, ``F``)
into ``dest/MiddEval3/{trainingR,testR}/<Scene>/`` (``im0.png``, ``im1.png``, ``calib.txt``,
and for training ``disp0GT.pfm``, ``mask0nocc.png``), which
:func:`sswjax.data.layouts.load_scenes` reads.
:func:`download_eth3d` unpacks ETH3D's ``two_view_training.7z`` and ``two_view_training_gt.7z``
into ``dest/ETH3D/`` (the layout :mod:`sswjax.data.layouts` reads); 7z needs ``py7zr`` (extra
``[eth3d]``). KITTI cannot be fetched: its site needs a registration (:data:`KITTI_HOWTO`).

Conventions: pooch fetches, checks hashes when known and moves archives into place; ours is
only what it lacks: resuming (:class:`ResumingDownloader`, with progress bar and size check),
safe atomic extraction, and one-line errors naming the URL or file, :class:`DownloadError`
(network, HTTP, size, checksum) or :class:`~sswjax._files.InputError` (files, bad archives).
:data:`MIDDEVAL3_REGISTRY` maps an archive to ``(size in bytes, "sha256:<hex>")``, each
``None`` while unknown (Middlebury publishes no checksums; pooch then gets ``known_hash=None``):
sizes are checked against it and the server's announcement, zip CRCs always. Downloads go to
``<archive>.part``, resumed by the next run when interrupted; ``.<archive>.extracted`` lists
what an archive gave, and reruns skip it while these files exist. Options with defaults are
keyword-only.
"""

from __future__ import annotations

import http.client
import os
import re
import shutil
import tempfile
import zipfile
import zlib
from pathlib import Path, PurePosixPath, PureWindowsPath
from urllib.error import URLError
from urllib.request import Request, urlopen

import pooch
from tqdm import tqdm

from sswjax._files import InputError, atomic_output, reason

__all__ = ["DEFAULT_BASE_URL", "MIDDEVAL3_ARCHIVES", "MIDDEVAL3_REGISTRY", "DownloadError",
           "ResumingDownloader", "download_middeval3", "middeval3_urls", "ETH3D_BASE_URL",
           "ETH3D_ARCHIVES", "download_eth3d", "KITTI_HOWTO"]  # fmt: skip

DEFAULT_BASE_URL = "https://vision.middlebury.edu/stereo/submit3/zip/"
#: Archives per resolution: images + calibration (both splits), training ground truth.
MIDDEVAL3_ARCHIVES = {r: (f"MiddEval3-data-{r}.zip", f"MiddEval3-GT0-{r}.zip") for r in "QHF"}
#: Archive -> (size in bytes or None, "sha256:<hex>" or None). Not recorded yet: fill them in
#: from a verified download (``pooch.file_hash`` gives the hash).
MIDDEVAL3_REGISTRY = {name: (None, None) for pair in MIDDEVAL3_ARCHIVES.values() for name in pair}
ETH3D_BASE_URL = "https://www.eth3d.net/data/"
#: ETH3D two-view training images (with calib.txt) and ground truth.
ETH3D_ARCHIVES = ("two_view_training.7z", "two_view_training_gt.7z")
#: What ``sswjax download kitti`` says: the data sits behind a registration.
KITTI_HOWTO = ("KITTI needs a registration at https://www.cvlibs.net/datasets/kitti/ (stereo "
               "2012: data_stereo_flow.zip; stereo 2015: data_scene_flow.zip): download it there "
               "and unpack it into DIR/KITTI2012 or DIR/KITTI2015 (DIR/KITTI2012/training/image_0, "
               "...), then run sswjax evaluate --data DIR/KITTI2012")
_NETWORK_ERRORS = (OSError, http.client.HTTPException)  # URLError and timeouts are OSErrors
_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, OSError, RuntimeError, NotImplementedError)


class DownloadError(InputError):
    """A download failed (network or HTTP error, size or checksum mismatch)."""


def _one_line(exc: BaseException | str) -> str:
    # A URLError's own text wraps its reason; its subclass HTTPError's text has the status code.
    return reason(exc.reason if type(exc) is URLError else exc)


class ResumingDownloader:
    """A pooch downloader (``downloader(url, output_file, pooch)``) that resumes downloads.

    The bytes go to ``part``; if it exists, only the missing ones are requested (``Range:
    bytes=N-``). A server ignoring the range (200) or refusing it (416) gets a full download.
    ``part`` becomes ``output_file`` once its size is the announced size and ``expected_size``;
    it is kept when the transfer is interrupted (the next call resumes it), deleted on a size
    mismatch. Errors are one-line :class:`DownloadError` naming the URL.

    Parameters
    ----------
    part : str or os.PathLike
        File keeping the bytes received so far, from one run to the next.
    expected_size : int, optional
        Required size in bytes.
    progress : bool
        Show a tqdm progress bar.
    timeout : float
        Seconds to wait for the connection and for each read.
    """

    def __init__(self, part: str | os.PathLike, *, expected_size: int | None = None,
                 progress: bool = True, timeout: float = 60.0) -> None:  # fmt: skip
        self.part, self.expected_size = Path(part), expected_size
        self.progress, self.timeout = progress, timeout

    def _request(self, url: str, offset: int):
        """``(response, offset of its body in the file, file size or None)``."""
        headers = {"User-Agent": "sswjax"} | ({"Range": f"bytes={offset}-"} if offset else {})
        try:
            response = urlopen(Request(url, headers=headers), timeout=self.timeout)
        except (*_NETWORK_ERRORS, ValueError) as exc:
            if getattr(exc, "code", None) == 416 and offset:  # range past the end: start over
                exc.close()
                return self._request(url, 0)
            raise DownloadError(f"cannot download {url}: {_one_line(exc)}") from exc
        if getattr(response, "status", None) != 206:
            return response, 0, getattr(response, "length", None)
        found = re.fullmatch(rf"bytes {offset}-\d+/(\d+)", str(response.headers["Content-Range"]))
        if found is None or not offset:
            response.close()
            raise DownloadError(f"cannot download {url}: unexpected partial response")
        return response, offset, int(found[1])

    def __call__(self, url: str, output_file: str | os.PathLike, pooch_instance=None) -> None:
        part, expected = self.part, self.expected_size
        response, received, total = self._request(url, part.stat().st_size if part.is_file() else 0)
        resume = f"run again to resume from {part}"
        if None not in (total, expected) and total != expected:
            response.close()
            received = total  # the size check below fails
        else:
            with response, open(part, "ab" if received else "wb") as f, tqdm(
                    total=total, initial=received, unit="B", unit_scale=True, unit_divisor=1024,
                    desc=Path(url).name, disable=not self.progress) as bar:  # fmt: skip
                try:
                    while chunk := response.read(1 << 16):
                        received += f.write(chunk)
                        bar.update(len(chunk))
                except _NETWORK_ERRORS as exc:  # also a full disk: resuming is then right too
                    reason = f"interrupted after {received} bytes ({_one_line(exc)})"
                    raise DownloadError(f"download of {url} {reason}; {resume}") from exc
        size = total if total is not None else expected
        if size is not None and received < size:
            raise DownloadError(f"download of {url} incomplete: {received} of {size} bytes; "
                                f"{resume}")  # fmt: skip
        if expected is not None and received != expected:
            part.unlink(missing_ok=True)
            raise DownloadError(f"size mismatch for {url}: {received} bytes, expected {expected}; "
                                f"partial file {part} deleted")  # fmt: skip
        os.replace(part, output_file)


def _unpack_into_place(extract_all, files: list[Path], dest: Path, top: Path) -> None:
    """``extract_all(folder)`` into a temporary folder in ``dest``, then each of ``files`` (its
    path under ``top`` as in the archive) moved onto its final path with ``os.replace``."""
    dest.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".extract-", dir=dest))
    try:
        extract_all(tmp)
        for final in files:
            final.parent.mkdir(parents=True, exist_ok=True)
            os.replace(tmp / final.relative_to(top), final)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _extract_zip(archive: Path, dest: Path) -> list[Path]:
    """Extract ``archive`` into ``dest`` atomically; return its files, in archive order.

    Unsafe names (absolute, drive, ``..``) or bad CRCs refuse it before anything is written;
    files go to a temporary folder in ``dest``, then onto their final paths with ``os.replace``.
    """
    try:
        zf = zipfile.ZipFile(archive)
    except (OSError, zipfile.BadZipFile) as exc:
        raise InputError(f"archive {archive} is not a valid zip file: {_one_line(exc)}") from exc
    with zf:
        for name in zf.namelist():
            parts = name.replace("\\", "/").split("/")
            if not parts[0] or ".." in parts or "\0" in name or PureWindowsPath(name).drive:
                raise InputError(f"archive {archive} has an unsafe member name {name[:80]!r}")
        try:
            bad = zf.testzip()
        except _ZIP_ERRORS as exc:
            raise InputError(f"archive {archive} is corrupt: {_one_line(exc)}") from exc
        if bad is not None:
            raise InputError(f"archive {archive} is corrupt: CRC check failed for {bad}")
        names = dict.fromkeys(i.filename for i in zf.infolist() if not i.is_dir())
        files = [dest / Path(*PurePosixPath(name).parts) for name in names]
        try:
            _unpack_into_place(zf.extractall, files, dest, dest)
        except _ZIP_ERRORS as exc:
            raise InputError(f"cannot extract {archive} into {dest}: {_one_line(exc)}") from exc
    return files


def middeval3_urls(*, resolution: str = "Q", base_url: str = DEFAULT_BASE_URL) -> list[str]:
    """URLs of the archives of one resolution, ``"Q"``, ``"H"`` or ``"F"`` (else ValueError).

    Examples
    --------
    >>> middeval3_urls(resolution="Q", base_url="http://example.org/zip")
    ['http://example.org/zip/MiddEval3-data-Q.zip', 'http://example.org/zip/MiddEval3-GT0-Q.zip']
    """
    if resolution not in MIDDEVAL3_ARCHIVES:
        raise ValueError(f"resolution must be one of Q, H, F, got {resolution!r}")
    return [base_url.rstrip("/") + "/" + name for name in MIDDEVAL3_ARCHIVES[resolution]]


def download_middeval3(dest: str | os.PathLike, *, resolution: str = "Q",
                       base_url: str = DEFAULT_BASE_URL, progress: bool = True,
                       keep_archives: bool = False) -> Path:  # fmt: skip
    """Download and unpack the MiddEval3 images, calibration and training ground truth.

    Archives whose files are all in place are skipped; the others are fetched by pooch with a
    :class:`ResumingDownloader` (or reused from ``dest``), checked (registry, CRCs; a bad one is
    deleted), extracted atomically, then deleted unless ``keep_archives``.

    Parameters
    ----------
    dest : str or os.PathLike
        Folder that receives ``MiddEval3/`` (created if missing).
    resolution : {"Q", "H", "F"}
        Quarter, half or full resolution.
    base_url : str
        Folder URL holding the archives.
    progress : bool
        Show tqdm progress bars.
    keep_archives : bool
        Keep the zip files in ``dest``.

    Returns
    -------
    pathlib.Path
        ``dest / "MiddEval3"``.

    Raises
    ------
    DownloadError
        If a download fails or does not match the registry.
    InputError
        If an archive is bad or unsafe, a file cannot be written, or no scene results.
    ValueError
        On an unknown resolution.
    """
    urls = middeval3_urls(resolution=resolution, base_url=base_url)
    urls, dest = dict(zip(MIDDEVAL3_ARCHIVES[resolution], urls)), Path(dest)
    _fetch_and_extract(dest, base_url, urls, {name: MIDDEVAL3_REGISTRY[name] for name in urls},
                       _extract_zip, progress=progress, keep_archives=keep_archives)
    split = dest / "MiddEval3" / f"training{resolution}"
    if not any(split.glob("*/im0.png")):
        raise InputError(f"the MiddEval3 archives did not produce {split}/<Scene>/im0.png")
    return dest / "MiddEval3"


def _fetch_and_extract(dest: Path, base_url: str, urls: dict, registry: dict, extract, *,
                       progress: bool, keep_archives: bool) -> None:
    """Fetch each archive ``name -> url`` (resuming; registry ``name -> (size, hash)``) unless
    the files it gave are all in place, extract it with ``extract(archive, dest)`` (a bad one
    is deleted), record what it gave in ``.<name>.extracted``, delete it unless kept."""
    fetcher = pooch.create(dest, base_url, urls=urls,
                           registry={name: registry[name][1] for name in urls})
    for name, url in urls.items():
        archive, marker = dest / name, dest / f".{name}.extracted"
        listed = marker.read_text().splitlines() if marker.is_file() else []
        if not listed or not all((dest / line).is_file() for line in listed):
            size = registry[name][0]
            resuming = ResumingDownloader(f"{archive}.part", expected_size=size, progress=progress)
            try:
                fetcher.fetch(name, downloader=resuming)
            except ValueError as exc:  # pooch's hash mismatch; ours are InputErrors
                if isinstance(exc, InputError):
                    raise
                raise DownloadError(f"checksum mismatch for {url}: {_one_line(exc)}") from exc
            try:
                files = extract(archive, dest)
            except InputError as exc:
                archive.unlink(missing_ok=True)
                raise InputError(f"{exc}; archive deleted, run again to fetch it anew") from exc
            with atomic_output(marker) as tmp:
                tmp.write_text("".join(f"{p.relative_to(dest).as_posix()}\n" for p in files))
        if not keep_archives:
            archive.unlink(missing_ok=True)


def _extract_7z(archive: Path, dest: Path) -> list[Path]:
    """Extract a 7z ``archive`` into ``dest`` atomically (as :func:`_extract_zip`); needs py7zr.

    Members outside a top folder named as the archive (``two_view_training/...`` for
    ``two_view_training.7z``) go into that folder, so either packing unpacks to one layout."""
    try:
        import py7zr
    except ImportError as exc:
        raise InputError(f"{archive.name} is a 7z archive: install py7zr to unpack it "
                         "(pip install py7zr, or the extra sswjax[eth3d])") from exc
    try:
        with py7zr.SevenZipFile(archive) as sz:
            infos = sz.list()
            for info in infos:
                parts = info.filename.replace("\\", "/").split("/")
                if (not parts[0] or ".." in parts or "\0" in info.filename
                        or PureWindowsPath(info.filename).drive):
                    raise InputError(f"archive {archive} has an unsafe member name "
                                     f"{info.filename[:80]!r}")
            names = [i.filename.replace("\\", "/") for i in infos if not i.is_directory]
            inside = all(name.startswith(archive.stem + "/") for name in names)
            top = dest if inside else dest / archive.stem
            files = [top / Path(*PurePosixPath(name).parts) for name in names]
            _unpack_into_place(sz.extractall, files, dest, top)
    except InputError:
        raise
    except Exception as exc:  # py7zr raises many types for bad archives  # noqa: BLE001
        raise InputError(f"archive {archive} is not a valid 7z archive: {_one_line(exc)}") from exc
    return files


def download_eth3d(dest: str | os.PathLike, *, base_url: str = ETH3D_BASE_URL,
                   progress: bool = True, keep_archives: bool = False) -> Path:  # fmt: skip
    """Download and unpack ETH3D's two-view training images and ground truth.

    As :func:`download_middeval3` (resuming, atomic extraction, reruns fetch only what is
    missing), into ``dest/ETH3D/two_view_training/<scene>/`` and
    ``dest/ETH3D/two_view_training_gt/<scene>/``. ETH3D publishes no checksums: the sizes the
    server announces are checked.

    Parameters
    ----------
    dest : str or os.PathLike
        Folder that receives ``ETH3D/`` (created if missing).
    base_url : str
        Folder URL holding the archives.
    progress, keep_archives : bool
        Progress bars; keep the 7z files in ``dest/ETH3D``.

    Returns
    -------
    pathlib.Path
        ``dest / "ETH3D"``, ready for ``sswjax evaluate --data``.

    Raises
    ------
    DownloadError
        If a download fails.
    InputError
        If py7zr is missing, an archive is bad or unsafe, or no scene results.

    Examples
    --------
    >>> download_eth3d("data")                        # doctest: +SKIP
    PosixPath('data/ETH3D')
    """
    root = Path(dest) / "ETH3D"
    try:
        import py7zr  # noqa: F401  (before any download: say what is missing first)
    except ImportError as exc:
        raise InputError("ETH3D's archives are 7z: install py7zr first (pip install py7zr, or "
                         "the extra sswjax[eth3d])") from exc
    urls = {name: base_url.rstrip("/") + "/" + name for name in ETH3D_ARCHIVES}
    _fetch_and_extract(root, base_url, urls, dict.fromkeys(urls, (None, None)), _extract_7z,
                       progress=progress, keep_archives=keep_archives)
    if not any((root / "two_view_training").glob("*/im0.png")):
        raise InputError(f"the ETH3D archives did not produce {root}/two_view_training/<scene>/im0.png")
    return root
