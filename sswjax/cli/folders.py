"""``sswjax match LEFT_DIR RIGHT_DIR --ndisp N -o OUT_DIR``: every pair of two folders.

The image files of the same name in both folders are pairs; each gives ``OUT_DIR/<stem>.pfm``.
Everything that can fail on the user's input is checked before the first pair runs, from the
files' headers: the folders, the names, each pair's sizes, ``ndisp`` against every width, the
output folder (neither LEFT_DIR nor RIGHT_DIR), and the memory estimate of the largest shape
(:mod:`sswjax.cli.guard`). Pairs run sorted by shape (the bucketed shape with ``--bucket``), so
each shape compiles once; each map is written atomically as soon as it is done, so Ctrl-C
keeps the finished ones and ``--resume`` skips them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from pathlib import Path
from typing import NamedTuple

from PIL import Image
from tqdm import tqdm

from sswjax._files import InputError, same_file
from sswjax._version import __version__
from sswjax.api.match import match
from sswjax.cli.common import Interrupted, command_line, resume_command
from sswjax.cli.guard import guard_memory
from sswjax.cli.options import params_from_args, plan_from_args
from sswjax.cli.record import RunRecord
from sswjax.data.io import read_image, read_pfm, write_pfm
from sswjax.runtime.buckets import ShapeBuckets, bucket_shape

__all__ = ["IMAGE_SUFFIXES", "FolderPair", "folder_pairs", "image_size", "match_folders"]

IMAGE_SUFFIXES = frozenset({".png", ".jpg", ".jpeg", ".ppm", ".pgm", ".pbm", ".pnm", ".bmp",
                            ".tif", ".tiff", ".webp"})
"""File name endings taken as images in a folder (any case); other files are ignored."""

_SINGLE_OUTPUTS = ("png", "confidence", "validity", "depth", "ply", "kitti_png")
"""``sswjax match`` options that name one output file (refused with folders)."""


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
            width, height = image.size
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


def _finished(path: Path, size) -> bool:
    """Whether ``path`` holds a readable PFM of the pair's size (what ``--resume`` keeps)."""
    if not path.is_file():
        return False
    try:
        return read_pfm(path).shape == tuple(size[:2])
    except (InputError, OSError):
        return False


AUTO_BUCKETS = 8
"""Distinct image sizes above which a folder run pads its pairs to shape buckets unless told
``--no-bucket``: each size is a compilation (seconds each), each bucket one."""


def _buckets(args: argparse.Namespace, pairs: list[FolderPair]) -> ShapeBuckets | None:
    """The shape buckets of a folder run: ``--bucket``, ``--no-bucket``, or, by default,
    buckets when the pairs come in more than :data:`AUTO_BUCKETS` sizes (said on stderr)."""
    if args.bucket is not None:
        return ShapeBuckets() if args.bucket else None
    sizes = {pair.size[:2] for pair in pairs}
    if len(sizes) <= AUTO_BUCKETS:
        return None
    print(f"sswjax: note: {len(sizes)} image sizes: padding them to shape buckets to compile "
          "fewer graphs (--no-bucket keeps every size)", file=sys.stderr)
    return ShapeBuckets()


def match_folders(args: argparse.Namespace) -> int:
    """``sswjax match LEFT_DIR RIGHT_DIR --ndisp N -o OUT_DIR [--resume] [--bucket]``;
    returns the exit status (0)."""
    if os.path.isdir(args.left) != os.path.isdir(args.right):
        folder, other = (args.left, args.right) if os.path.isdir(args.left) else (args.right, args.left)
        raise InputError(f"LEFT and RIGHT must be two image files or two folders: {folder} is a "
                         f"folder, {other} is not")
    given = [f"--{name.replace('_', '-')}" for name in _SINGLE_OUTPUTS
             if getattr(args, name, None) is not None]
    if given:
        raise ValueError(f"{given[0]} names one file: with folders only -o OUT_DIR is written")
    out = args.output
    for name, folder in (("LEFT_DIR", args.left), ("RIGHT_DIR", args.right)):
        if same_file(out, folder):
            raise ValueError(f"-o {out} is the same folder as {name} {folder}: the maps go to "
                             "a folder of their own")
    if out.exists() and not out.is_dir():
        raise ValueError(f"output {out} is a file: with folders -o names a folder")
    if not out.parent.is_dir():
        raise ValueError(f"output folder does not exist: {out.parent}")
    params, execution = params_from_args(args)
    min_disp = getattr(args, "min_disp", 0) or 0
    pairs = folder_pairs(args.left, args.right)
    buckets = _buckets(args, pairs)
    plan = plan_from_args(args, execution, buckets=buckets)
    settings = {"command": "match", "version": __version__, "params": params.to_dict(),
                "ndisp": args.ndisp, "min_disp": min_disp, "strip_rows": plan.strip_rows,
                "strip_overlap": plan.strip_overlap,
                "buckets": None if buckets is None else list(buckets)}
    narrowest = min(pairs, key=lambda p: p.size[1])
    if min_disp == 0 and not 1 <= args.ndisp < narrowest.size[1]:
        raise ValueError(f"ndisp must be in [1, {narrowest.size[1] - 1}] for the narrowest pair "
                         f"{narrowest.name}, got {args.ndisp}")
    plan = guard_memory([p.size for p in pairs], args.ndisp, params=params, plan=plan,
                        limit_gb=args.max_memory, min_disp=min_disp)

    def shape(pair):
        height, width = pair.size[:2]
        return (bucket_shape(height, width, args.ndisp, buckets) if buckets else (height, width),
                pair.name)

    pairs.sort(key=shape)
    out.mkdir(exist_ok=True)
    record = (RunRecord.resume if args.resume else RunRecord.start)(out, settings)
    targets = [out / f"{Path(p.name).stem}.pfm" for p in pairs]
    done = [record.done(t.name) and _finished(t, p.size) for p, t in zip(pairs, targets)]
    start, resumed = time.perf_counter(), sum(done)
    try:
        with tqdm(total=len(pairs), initial=resumed, desc="pairs", unit="pair",
                  file=sys.stderr) as bar:
            for i, (pair, target) in enumerate(zip(pairs, targets)):
                if done[i]:
                    continue
                bar.set_postfix_str(pair.name)
                left, right = read_image(pair.left), read_image(pair.right)
                disparity = match(left, right, args.ndisp, min_disp=min_disp, params=params,
                                  plan=plan, check_memory=False)  # guard_memory checked it
                write_pfm(target, disparity)
                record.finished(target.name)
                done[i] = True
                bar.update(1)
    except KeyboardInterrupt:
        raise Interrupted(f"interrupted; {sum(done)} of {len(pairs)} disparity maps are saved in "
                          f"{out}; continue with: {resume_command(command_line(args))}") from None
    note = f", {resumed} kept from before" if resumed else ""
    print(f"wrote {len(pairs) - resumed} disparity maps to {out}{note} "
          f"({len({shape(p)[0] for p in pairs})} shapes, {time.perf_counter() - start:.1f} s)")
    return 0
