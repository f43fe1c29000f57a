"""The pairs of two folders: the image files of the same name in both, with their sizes read
from the headers (what a folder run checks before it matches anything).

:func:`checked_pairs` separates the good pairs from the bad ones (an image that cannot be read,
two sizes), so that a run can match the good ones and name the others; :func:`folder_pairs`
refuses the folders when any pair is bad (``--strict``)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import NamedTuple

from PIL import Image

from sswjax._files import InputError, first_line, input_file
from sswjax.data.io import read_image
from sswjax.data.orientation import upright_size

__all__ = ["IMAGE_SUFFIXES", "FolderPair", "bad_pairs_error", "checked_pairs", "folder_pairs",
           "image_size"]

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
    input_file(path, "image")  # a FIFO is refused, not opened (its open would wait)
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


def checked_pairs(left_dir: str | Path, right_dir: str | Path
                  ) -> tuple[list[FolderPair], dict[str, str]]:
    """The good pairs of two folders (the image files of the same name in both, with their
    sizes, sorted by name) and the bad ones: name -> why, one line starting ``pair NAME:`` (an
    image that cannot be read, a left and a right image of two sizes).

    Raises
    ------
    InputError
        For the folders as a whole: no name is common to both, or two common names share a
        stem (their outputs would collide).

    Examples
    --------
    >>> good, bad = checked_pairs("left", "right")       # doctest: +SKIP
    >>> [p.name for p in good], bad                      # doctest: +SKIP
    (['a.png'], {'b.png': 'pair b.png: cannot read image left/b.png: not an image file ...'})
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
    pairs, bad = [], {}
    for name in names:
        try:
            left, right = image_size(lefts[name]), image_size(rights[name])
        except (ValueError, OSError) as error:  # read_image's InputError, one line
            bad[name] = f"pair {name}: {first_line(error)}"
            continue
        if left[:2] != right[:2]:
            bad[name] = (f"pair {name}: left {left[1]}x{left[0]} and right "
                         f"{right[1]}x{right[0]} differ in size")
            continue
        pairs.append(FolderPair(name, lefts[name], rights[name],
                                (left[0], left[1], max(left[2], right[2]))))
    return pairs, bad


def bad_pairs_error(bad: dict[str, str]) -> InputError:
    """The one-line refusal of folders with the bad pairs ``bad`` (as :func:`checked_pairs`
    gives them): the first named with why, the others counted and named.

    Examples
    --------
    >>> str(bad_pairs_error({"b.png": "pair b.png: unreadable", "c.png": "pair c.png: sizes"}))
    'pair b.png: unreadable; 1 more bad pair: c.png'
    """
    first, *others = sorted(bad)
    more = (f"; {len(others)} more bad pair{'s' if len(others) > 1 else ''}: "
            f"{', '.join(others)}" if others else "")
    return InputError(f"{bad[first]}{more}")


def folder_pairs(left_dir: str | Path, right_dir: str | Path) -> list[FolderPair]:
    """The image files of the same name in both folders, with their sizes, sorted by name;
    every pair must be good (:func:`checked_pairs` takes the good ones and names the others).

    Raises
    ------
    InputError
        If no name is common to both, two common names share a stem (their outputs would
        collide), or a pair is bad: an image cannot be read, or the two differ in size (one
        line, :func:`bad_pairs_error`).

    Examples
    --------
    >>> [p.name for p in folder_pairs("left", "right")]  # doctest: +SKIP
    ['a.png', 'b.png']
    """
    pairs, bad = checked_pairs(left_dir, right_dir)
    if bad:
        raise bad_pairs_error(bad)
    return pairs
