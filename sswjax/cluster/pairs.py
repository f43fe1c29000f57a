"""The pairs of two folders: the image files of the same name in both, with their sizes read
from the headers (what a folder run checks before it matches anything)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import NamedTuple

from PIL import Image

from sswjax._files import InputError
from sswjax.data.io import read_image
from sswjax.data.orientation import upright_size

__all__ = ["IMAGE_SUFFIXES", "FolderPair", "folder_pairs", "image_size"]

IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".pbm", ".pnm", ".bmp",
                            ".tif", ".tiff", ".webp"})
"""File name endings taken as images in a folder (any case); other files are ignored."""


class FolderPair(NamedTuple):
    """One pair of a folder run: its file name, files and size ``(height, width, channels)``."""

    name: str
    left: Path
    right: Path
    size: tuple[int, int, int]


def image_size(path: str | Path) -> tuple[int, int, int]:
    """``(height, width, channels)`` of an image from its header; channels 1 (gray) or 3.

    Pillow reads only the header; a file it cannot open is read whole by
    :func:`sswjax.data.io.read_image`, which raises its one-line ``InputError``.

    Examples
    --------
    >>> image_size("Motorcycle/im0.png")                # doctest: +SKIP
    (497, 741, 3)
    """
    try:
        with Image.open(path) as image:
            height, width = upright_size(image)  # as read_image turns it (EXIF)
            gray = image.mode in ("1", "L", "LA", "I", "I;16", "I;16B", "I;16L", "F")
            return height, width, 1 if gray else 3
    except Exception:  # noqa: BLE001 (any failure: read_image gives the message)
        image = read_image(path)
        return image.shape[0], image.shape[1], 1 if image.ndim == 2 else 3


def _images(folder: Path) -> dict[str, Path]:
    return {p.name: p for p in sorted(folder.iterdir())
            if p.suffix.lower() in IMAGE_SUFFIXES and not p.name.startswith(".") and p.is_file()}


def folder_pairs(left_dir: str | Path, right_dir: str | Path) -> list[FolderPair]:
    """The image files of the same name in both folders, with their sizes, sorted by name.

    Raises
    ------
    InputError
        If no name is common to both, two common names share a stem (their outputs would
        collide), or a pair's images differ in size (one line each).

    Examples
    --------
    >>> [p.name for p in folder_pairs("left", "right")]  # doctest: +SKIP
    ['a.png', 'b.png']
    """
    left_dir, right_dir = Path(left_dir), Path(right_dir)
    lefts, rights = _images(left_dir), _images(right_dir)
    names = [name for name in lefts if name in rights]
    if not names:
        raise InputError(f"no image file names in common between {left_dir} ({len(lefts)} "
                         f"images) and {right_dir} ({len(rights)} images)")
    stems = Counter(Path(name).stem for name in names)
    clash = sorted(name for name in names if stems[Path(name).stem] > 1)
    if clash:
        raise InputError(f"images {', '.join(clash)} in {left_dir} would write the same "
                         f"{Path(clash[0]).stem}.pfm: rename one")
    pairs = []
    for name in names:
        left, right = image_size(lefts[name]), image_size(rights[name])
        if left[:2] != right[:2]:
            raise InputError(f"pair {name}: left {left[1]}x{left[0]} and right "
                             f"{right[1]}x{right[0]} differ in size")
        pairs.append(FolderPair(name, lefts[name], rights[name],
                                (left[0], left[1], max(left[2], right[2]))))
    return pairs
