"""Downloading the Middlebury MiddEval3 stereo data.

Layout produced
---------------
:func:`download_middeval3` fetches, for one resolution ``R`` in ``Q``/``H``/``F``, the
archives listed in :data:`MIDDEVAL3_ARCHIVES` (images + calibration for the training and
test splits, and the training ground truth) and unpacks them into ``dest``::

    dest/MiddEval3/trainingR/<Scene>/im0.png, im1.png, calib.txt, disp0GT.pfm, mask0nocc.png
    dest/MiddEval3/testR/<Scene>/im0.png, im1.png, calib.txt

which is what :func:`sswjax.data.datasets.load_middeval3` reads (pass it ``dest / "MiddEval3"``).

Resume and verification
-----------------------
:func:`download_file` writes to ``<dest>.part`` and resumes an existing ``.part`` with an
HTTP ``Range`` request (a server that ignores it is handled by starting over). The file is
renamed onto its final name only once its size matches the size the server announced
(``Content-Length`` / ``Content-Range``) and, when given, ``expected_size`` and ``sha256``.
An interrupted transfer keeps the ``.part`` so that the next call resumes it; a size or
checksum mismatch deletes it. :func:`extract_zip` checks every member's CRC and refuses
unsafe member names before writing anything, and moves files into place only after the whole
archive has been extracted to a temporary folder.

Middlebury does not publish checksums of its archives, so by default they are verified by
their ``Content-Length`` and the zip CRCs only; pass ``sha256`` to :func:`download_file` for
a stronger check.

Every failure raises :class:`DownloadError` (network, size, checksum) or
:class:`~sswjax.data.io.InputError` (local files, corrupt or unsafe archives) with a one-line
message naming the URL or file; :class:`DownloadError` is a subclass of ``InputError``.
"""

from __future__ import annotations

import hashlib
import http.client
import os
import re
import shutil
import tempfile
import urllib.error
import urllib.request
import zipfile
import zlib
from pathlib import Path, PurePosixPath, PureWindowsPath

from tqdm import tqdm

from sswjax.data.io import InputError, atomic_output

__all__ = [
    "DEFAULT_BASE_URL",
    "MIDDEVAL3_ARCHIVES",
    "DownloadError",
    "download_file",
    "download_middeval3",
    "extract_zip",
    "middeval3_urls",
]

DEFAULT_BASE_URL = "https://vision.middlebury.edu/stereo/submit3/zip/"

#: Archive names per resolution: images + calibration (training and test), then the
#: training ground truth (``disp0GT.pfm`` + ``mask0nocc.png``). Each unpacks into ``MiddEval3/``.
MIDDEVAL3_ARCHIVES: dict[str, tuple[str, ...]] = {
    "Q": ("MiddEval3-data-Q.zip", "MiddEval3-GT0-Q.zip"),
    "H": ("MiddEval3-data-H.zip", "MiddEval3-GT0-H.zip"),
    "F": ("MiddEval3-data-F.zip", "MiddEval3-GT0-F.zip"),
}

_USER_AGENT = "sswjax-download/0.1 (Python urllib)"
# Everything urllib / http.client / sockets raise for a failed or interrupted transfer
# (URLError and HTTPError are OSError subclasses; socket timeouts are TimeoutError).
_NETWORK_ERRORS = (OSError, http.client.HTTPException)


class DownloadError(InputError):
    """A download failed (network error, HTTP error, size or checksum mismatch)."""


# ----------------------------------------------------------------------------- helpers


def _one_line(exc: BaseException | str) -> str:
    """First line of an exception's (or reason's) message, for one-line error reports."""
    if isinstance(exc, urllib.error.HTTPError):
        text = f"HTTP {exc.code} {exc.reason}"
    elif isinstance(exc, urllib.error.URLError):
        text = _one_line(exc.reason) if isinstance(exc.reason, BaseException) else str(exc.reason)
    elif isinstance(exc, BaseException):
        text = getattr(exc, "strerror", None) or str(exc).strip() or type(exc).__name__
    else:
        text = str(exc)
    text = text.strip()
    return text.splitlines()[0] if text else "unknown error"


def _content_length(headers) -> int | None:
    value = headers.get("Content-Length")
    if value is None or not value.strip().isdigit():
        return None
    return int(value)


def _content_range(value: str | None) -> tuple[int | None, int | None]:
    """Parse ``bytes start-end/total`` (or ``bytes */total``) into ``(start, total)``."""
    match = re.fullmatch(r"\s*bytes\s+(?:(\d+)-\d+|\*)/(\d+|\*)\s*", value or "")
    if match is None:
        return None, None
    start = int(match[1]) if match[1] is not None else None
    total = int(match[2]) if match[2] != "*" else None
    return start, total


def _open(url: str, offset: int, timeout: float):
    """Open ``url`` asking for bytes from ``offset`` on.

    Returns ``(response, offset, total)``: ``offset`` is where the body starts (0 when the
    server sends the whole file), ``total`` the full file size if the server announced it.
    ``response`` is ``None`` when the server says the range is past the end and the ``.part``
    has exactly the announced size (or the size is unknown): the file is already complete.
    """
    headers = {"User-Agent": _USER_AGENT, "Accept-Encoding": "identity"}
    if offset > 0:
        headers["Range"] = f"bytes={offset}-"
    try:
        response = urllib.request.urlopen(
            urllib.request.Request(url, headers=headers), timeout=timeout
        )
    except urllib.error.HTTPError as exc:
        if exc.code == 416 and offset > 0:
            _, total = _content_range(exc.headers.get("Content-Range"))
            exc.close()
            if total is None or total == offset:
                return None, offset, offset
            return _open(url, 0, timeout)  # the .part does not match the file: start over
        raise DownloadError(f"cannot download {url}: {_one_line(exc)}") from exc
    except (*_NETWORK_ERRORS, ValueError) as exc:
        raise DownloadError(f"cannot download {url}: {_one_line(exc)}") from exc

    status = getattr(response, "status", None)
    if status == 206:
        start, total = _content_range(response.headers.get("Content-Range"))
        if start != offset:
            response.close()
            if offset == 0:
                raise DownloadError(
                    f"cannot download {url}: unexpected partial response "
                    f"(Content-Range {response.headers.get('Content-Range')!r})"
                )
            return _open(url, 0, timeout)
        if total is None:
            length = _content_length(response.headers)
            total = None if length is None else offset + length
        return response, offset, total
    if status not in (200, None):  # None: file:// and other non-HTTP URLs
        response.close()
        raise DownloadError(f"cannot download {url}: unexpected HTTP status {status}")
    return response, 0, _content_length(response.headers)


def _hash_file(path: Path, hasher, chunk_size: int) -> None:
    with open(path, "rb") as f:
        while chunk := f.read(chunk_size):
            hasher.update(chunk)


def _file_size(path: Path) -> int:
    try:
        return path.stat().st_size if path.is_file() else 0
    except OSError:
        return 0


# ----------------------------------------------------------------------------- download


def download_file(
    url: str,
    dest: str | os.PathLike,
    *,
    expected_size: int | None = None,
    sha256: str | None = None,
    progress: bool = True,
    chunk_size: int = 1 << 16,
    timeout: float = 60,
) -> Path:
    """Download ``url`` to ``dest``, resuming a partial download, and verify it.

    The data goes to ``dest`` + ``".part"``. If that file exists, only the missing bytes are
    requested (``Range: bytes=N-``); a server that answers with the whole file (200) is
    handled by starting over, one that answers 416 (range past the end) means the ``.part``
    is already complete. The ``.part`` is renamed onto ``dest`` only after its size matches
    the size announced by the server and ``expected_size``, and its SHA-256 matches
    ``sha256`` (when given). An existing ``dest`` is replaced.

    Parameters
    ----------
    url : str
        URL to fetch (``http``, ``https``, ``file``, ...).
    dest : str or os.PathLike
        Final file; missing parent folders are created.
    expected_size : int, optional
        Required size in bytes.
    sha256 : str, optional
        Required SHA-256 as 64 hex digits (case-insensitive).
    progress : bool
        Show a tqdm progress bar.
    chunk_size : int
        Bytes read per network call.
    timeout : float
        Seconds to wait for the connection and for each read.

    Returns
    -------
    pathlib.Path
        ``dest``.

    Raises
    ------
    DownloadError
        On a network or HTTP error or an interrupted transfer (the ``.part`` is kept so that
        a new call resumes it), or a size or checksum mismatch (the ``.part`` is deleted).
    InputError
        If ``dest`` or its ``.part`` cannot be written.
    ValueError
        On a bad ``expected_size``, ``sha256``, ``chunk_size`` or ``timeout``.

    Examples
    --------
    >>> download_file(  # doctest: +SKIP
    ...     "https://vision.middlebury.edu/stereo/submit3/zip/MiddEval3-GT0-Q.zip",
    ...     "data/MiddEval3-GT0-Q.zip",
    ... )
    PosixPath('data/MiddEval3-GT0-Q.zip')
    """
    if expected_size is not None and (isinstance(expected_size, bool) or expected_size < 0):
        raise ValueError(f"expected_size must be a non-negative integer, got {expected_size!r}")
    if sha256 is not None and re.fullmatch(r"[0-9a-fA-F]{64}", sha256) is None:
        raise ValueError(f"sha256 must be 64 hexadecimal digits, got {sha256!r}")
    if chunk_size < 1:
        raise ValueError(f"chunk_size must be positive, got {chunk_size}")
    if not timeout > 0:
        raise ValueError(f"timeout must be positive, got {timeout}")
    dest = Path(dest)
    part = dest.with_name(dest.name + ".part")
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {dest.parent}: {_one_line(exc)}") from exc

    offset = _file_size(part)
    if expected_size is not None and offset > expected_size:
        part.unlink(missing_ok=True)  # longer than the whole file: not a prefix of it
        offset = 0
    response, offset, total = _open(url, offset, timeout)

    def mismatch(message: str) -> DownloadError:
        part.unlink(missing_ok=True)
        return DownloadError(f"{message} for {url}; partial file {part} deleted")

    if total is not None and expected_size is not None and total != expected_size:
        if response is not None:
            response.close()
        raise mismatch(f"size mismatch: server reports {total} bytes, expected {expected_size}")

    hasher = hashlib.sha256() if sha256 is not None else None
    received = offset
    try:
        if hasher is not None and offset > 0:
            _hash_file(part, hasher, chunk_size)
        if response is not None:
            with response, open(part, "ab" if offset > 0 else "wb") as f, tqdm(
                total=total,
                initial=offset,
                unit="B",
                unit_scale=True,
                unit_divisor=1024,
                desc=dest.name,
                disable=not progress,
            ) as bar:
                while True:
                    try:
                        chunk = response.read(chunk_size)
                    except _NETWORK_ERRORS as exc:
                        raise DownloadError(
                            f"download of {url} interrupted after {received} bytes "
                            f"({_one_line(exc)}); run again to resume from {part}"
                        ) from exc
                    if not chunk:
                        break
                    f.write(chunk)
                    received += len(chunk)
                    if hasher is not None:
                        hasher.update(chunk)
                    bar.update(len(chunk))
                    if total is not None and received > total:
                        break
    except DownloadError:
        raise
    except OSError as exc:
        raise InputError(f"cannot write {part}: {_one_line(exc)}") from exc

    if total is not None and received > total:
        raise mismatch(f"size mismatch: received more than the announced {total} bytes")
    if total is not None and received < total:
        raise DownloadError(
            f"download of {url} incomplete: connection closed after {received} of {total} "
            f"bytes; run again to resume from {part}"
        )
    if expected_size is not None and received > expected_size:
        raise mismatch(f"size mismatch: received {received} bytes, expected {expected_size}")
    if expected_size is not None and received < expected_size:
        raise DownloadError(
            f"download of {url} incomplete: connection closed after {received} of "
            f"{expected_size} bytes; run again to resume from {part}"
        )
    if hasher is not None and hasher.hexdigest() != sha256.lower():
        raise mismatch(f"checksum mismatch: sha256 {hasher.hexdigest()}, expected {sha256.lower()}")
    try:
        os.replace(part, dest)
    except OSError as exc:
        raise InputError(f"cannot move {part} to {dest}: {_one_line(exc)}") from exc
    return dest


# ----------------------------------------------------------------------------- extraction


def _unsafe_member(name: str) -> bool:
    """True for member names that are absolute or climb out of the target folder."""
    if not name or "\x00" in name:
        return True
    if PurePosixPath(name).is_absolute() or name.startswith("\\"):
        return True
    if PureWindowsPath(name).drive:
        return True
    return ".." in name.replace("\\", "/").split("/")


def extract_zip(archive: str | os.PathLike, dest_root: str | os.PathLike) -> list[Path]:
    """Safely extract a zip archive into ``dest_root``.

    Before anything is written, every member name is checked (absolute paths, drive letters
    and ``..`` components are refused: no "zip slip") and every member's CRC is verified with
    :meth:`zipfile.ZipFile.testzip`. The archive is then extracted into a temporary folder
    inside ``dest_root`` and each file is moved into place with ``os.replace``, so no
    half-written file ever appears at its final path. Existing files are overwritten.

    Parameters
    ----------
    archive : str or os.PathLike
        Zip file.
    dest_root : str or os.PathLike
        Folder that receives the archive's tree (created if missing).

    Returns
    -------
    list of pathlib.Path
        The extracted files (not folders), in archive order.

    Raises
    ------
    InputError
        If the archive is missing, not a zip file, corrupt (bad CRC or data), encrypted,
        has an unsafe member name, or cannot be extracted into ``dest_root``.

    Examples
    --------
    >>> files = extract_zip("MiddEval3-data-Q.zip", "data")  # doctest: +SKIP
    >>> files[0]  # doctest: +SKIP
    PosixPath('data/MiddEval3/trainingQ/Adirondack/calib.txt')
    """
    archive, dest_root = Path(archive), Path(dest_root)
    if not archive.is_file():
        raise InputError(f"archive not found: {archive}")
    try:
        zf = zipfile.ZipFile(archive)
    except (zipfile.BadZipFile, OSError) as exc:
        raise InputError(f"archive {archive} is not a valid zip file: {_one_line(exc)}") from exc
    with zf:
        members = zf.infolist()
        for info in members:
            if _unsafe_member(info.filename):
                raise InputError(
                    f"archive {archive} has an unsafe member name {info.filename[:80]!r} "
                    "(absolute or with '..'); nothing extracted"
                )
        try:
            bad = zf.testzip()
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, RuntimeError,
                NotImplementedError) as exc:  # fmt: skip
            raise InputError(f"archive {archive} is corrupt: {_one_line(exc)}") from exc
        if bad is not None:
            raise InputError(f"archive {archive} is corrupt: CRC check failed for {bad}")

        try:
            dest_root.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=".extract-", dir=dest_root))
        except OSError as exc:
            raise InputError(f"cannot create folder in {dest_root}: {_one_line(exc)}") from exc
        try:
            extracted: list[Path] = []
            seen: set[Path] = set()
            try:
                zf.extractall(tmp)
                for info in members:
                    relative = Path(*PurePosixPath(info.filename).parts)
                    final = dest_root / relative
                    if info.is_dir():
                        final.mkdir(parents=True, exist_ok=True)
                        continue
                    if relative in seen:  # duplicate name: extractall kept the last one
                        continue
                    seen.add(relative)
                    final.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(tmp / relative, final)
                    extracted.append(final)
            except (OSError, zipfile.BadZipFile, zlib.error, EOFError) as exc:
                raise InputError(
                    f"cannot extract {archive} into {dest_root}: {_one_line(exc)}"
                ) from exc
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return extracted


# ----------------------------------------------------------------------------- MiddEval3


def middeval3_urls(resolution: str = "Q", *, base_url: str = DEFAULT_BASE_URL) -> list[str]:
    """URLs of the MiddEval3 archives for one resolution.

    Parameters
    ----------
    resolution : {"Q", "H", "F"}
        Quarter, half or full resolution.
    base_url : str
        Folder URL holding the archives (a trailing ``/`` is added if missing).

    Returns
    -------
    list of str
        One URL per entry of ``MIDDEVAL3_ARCHIVES[resolution]``.

    Raises
    ------
    ValueError
        On an unknown resolution.

    Examples
    --------
    >>> middeval3_urls("Q", base_url="http://example.org/zip")
    ['http://example.org/zip/MiddEval3-data-Q.zip', 'http://example.org/zip/MiddEval3-GT0-Q.zip']
    """
    if resolution not in MIDDEVAL3_ARCHIVES:
        choices = ", ".join(MIDDEVAL3_ARCHIVES)
        raise ValueError(f"resolution must be one of {choices}, got {resolution!r}")
    base = base_url if base_url.endswith("/") else base_url + "/"
    return [base + name for name in MIDDEVAL3_ARCHIVES[resolution]]


def _marker(dest: Path, archive_name: str) -> Path:
    """Hidden file listing what an archive extracted (relative to ``dest``)."""
    return dest / f".{archive_name}.extracted"


def _already_extracted(dest: Path, archive_name: str) -> bool:
    marker = _marker(dest, archive_name)
    try:
        listed = marker.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return False
    return bool(listed) and all((dest / line).is_file() for line in listed)


def download_middeval3(
    dest: str | os.PathLike,
    *,
    resolution: str = "Q",
    base_url: str = DEFAULT_BASE_URL,
    progress: bool = True,
    keep_archives: bool = False,
) -> Path:
    """Download and unpack the MiddEval3 images, calibration and training ground truth.

    For each archive of ``MIDDEVAL3_ARCHIVES[resolution]``: skip it if a previous run
    already extracted it and all its files are still there; otherwise download it into
    ``dest`` (unless the verified zip is already there; an interrupted download is resumed)
    and extract it. Archives are deleted afterwards unless ``keep_archives``. Running it again
    is cheap and repairs missing files.

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
        Keep the downloaded zip files in ``dest``.

    Returns
    -------
    pathlib.Path
        ``dest / "MiddEval3"``, ready for :func:`sswjax.data.datasets.load_middeval3`.

    Raises
    ------
    DownloadError
        If a download fails (see :func:`download_file`).
    InputError
        If an archive is corrupt or unsafe, files cannot be written, or the result has no
        ``MiddEval3/training<R>/<Scene>/im0.png``.
    ValueError
        On an unknown resolution.

    Examples
    --------
    >>> root = download_middeval3("data", resolution="Q")  # doctest: +SKIP
    >>> from sswjax.data.datasets import load_middeval3  # doctest: +SKIP
    >>> len(load_middeval3(root, split="trainingQ"))  # doctest: +SKIP
    15
    """
    urls = middeval3_urls(resolution, base_url=base_url)
    dest = Path(dest)
    try:
        dest.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {dest}: {_one_line(exc)}") from exc

    for url, name in zip(urls, MIDDEVAL3_ARCHIVES[resolution]):
        archive = dest / name
        if not _already_extracted(dest, name):
            existed = archive.is_file()
            if not existed:
                download_file(url, archive, progress=progress)
            try:
                files = extract_zip(archive, dest)
            except InputError as exc:
                if existed:  # not verified by us in this run: tell the user what to do
                    raise InputError(f"{exc}; delete it and run again") from exc
                raise
            with atomic_output(_marker(dest, name)) as tmp:
                tmp.write_text(
                    "".join(f"{p.relative_to(dest).as_posix()}\n" for p in files),
                    encoding="utf-8",
                )
        if not keep_archives:
            try:
                archive.unlink(missing_ok=True)
            except OSError as exc:
                raise InputError(f"cannot delete {archive}: {_one_line(exc)}") from exc

    root = dest / "MiddEval3"
    split = root / f"training{resolution}"
    if not any(split.glob("*/im0.png")):
        raise InputError(
            f"the MiddEval3 archives did not produce {split}/<Scene>/im0.png; "
            "has the archive layout changed?"
        )
    return root
