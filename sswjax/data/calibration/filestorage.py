"""A plain reader of the YAML and XML files of OpenCV's ``cv2.FileStorage`` (and of ROS's
camera_info YAML), so that reading a calibration does not need OpenCV.

The YAML read is the subset those tools write: the ``%YAML:1.0`` header and ``---``, comments,
block mappings nested by indentation, tags (``!!opencv-matrix``: the mapping that follows is
the matrix), flow sequences ``[ 1., 0., ... ]`` over several lines, block sequences ``- 1.0``,
numbers (``.nan``, ``.inf`` too) and strings, quoted or not. The XML is ``<opencv_storage>``
with one element per key: ``type_id="opencv-matrix"`` elements hold ``rows cols dt data``,
others numbers separated by spaces, text, or nested elements.

Both give the same values: dicts, lists, floats (integers as ``int``), strings; a matrix is
the mapping ``{"rows", "cols", "dt", "data"}`` (:func:`sswjax.data.calibration.common.matrix`
turns it into an array).
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree

from sswjax._files import InputError, first_line
from sswjax.data.calibration.common import read_text

__all__ = ["parse_xml", "parse_yaml", "read_filestorage", "scalar"]

_SPECIAL = {".nan": float("nan"), ".inf": float("inf"), "+.inf": float("inf"),
            "-.inf": float("-inf"), "true": True, "false": False, "null": None, "~": None}


def scalar(text: str):
    """A YAML scalar: int, float, bool, None or the (unquoted) string.

    Examples
    --------
    >>> scalar("640"), scalar("1.e-3"), scalar("0."), scalar("'d'"), scalar("plumb_bob")
    (640, 0.001, 0.0, 'd', 'plumb_bob')
    """
    text = text.strip()
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "'\"":
        return text[1:-1]
    if text.lower() in _SPECIAL:
        return _SPECIAL[text.lower()]
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def _strip_comment(line: str) -> str:
    quote = None
    for i, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


def _flow(text: str, path: Path, number: int):
    """A flow value: ``[a, b, [c]]``, ``{k: v}`` or a scalar."""
    text = text.strip()
    if not text.startswith(("[", "{")):
        return scalar(text)
    closing = "]" if text[0] == "[" else "}"
    if not text.endswith(closing):
        raise InputError(f"calibration file {path} line {number}: unclosed {text[0]}")
    items, depth, current = [], 0, []
    for char in text[1:-1]:
        depth += (char in "[{") - (char in "]}")
        if char == "," and depth == 0:
            items.append("".join(current))
            current = []
        else:
            current.append(char)
    items = [item.strip() for item in items + ["".join(current)] if item.strip()]
    if text[0] == "[":
        return [_flow(item, path, number) for item in items]
    pairs = {}
    for item in items:
        key, sep, value = item.partition(":")
        if not sep:
            raise InputError(f"calibration file {path} line {number}: {item!r} is not key: value")
        if key.strip() in pairs:
            raise InputError(f"calibration file {path} line {number}: {key.strip()} given twice")
        pairs[key.strip()] = _flow(value, path, number)
    return pairs


def _untag(text: str) -> str:
    """``!!opencv-matrix rest`` -> ``rest`` (any tag)."""
    return re.sub(r"^!\S*\s*", "", text.strip())


def parse_yaml(text: str, path: Path) -> dict:
    """The top-level mapping of a FileStorage or camera_info YAML text (module docstring).

    Raises ``InputError`` (one line, with the line number) on what it cannot read, and on a
    key given twice in one mapping.

    Examples
    --------
    >>> parse_yaml("%YAML:1.0\\n---\\nK1: !!opencv-matrix\\n   rows: 1\\n   cols: 2\\n"
    ...            "   dt: d\\n   data: [ 1., 2. ]\\nwidth: 640\\n", Path("s.yaml"))
    {'K1': {'rows': 1, 'cols': 2, 'dt': 'd', 'data': [1.0, 2.0]}, 'width': 640}
    """
    lines = []  # (indent, content, line number), flow values joined over their lines
    pending = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw).rstrip()
        if pending is not None:
            pending = (pending[0], pending[1] + " " + line.strip(), pending[2])
            if _balanced(pending[1]):
                lines.append(pending)
                pending = None
            continue
        stripped = line.strip()
        if not stripped or stripped.startswith("%") or stripped in ("---", "..."):
            continue
        if "\t" in line[: len(line) - len(line.lstrip())]:
            raise InputError(f"calibration file {path} line {number}: tabs in the indentation")
        entry = (len(line) - len(line.lstrip()), stripped, number)
        if _balanced(stripped):
            lines.append(entry)
        else:
            pending = entry
    if pending is not None:
        raise InputError(f"calibration file {path} line {pending[2]}: unclosed bracket")
    if not lines:
        raise InputError(f"calibration file {path} is empty")
    value, end = _block(lines, 0, lines[0][0], path)
    if end < len(lines):
        raise InputError(f"calibration file {path} line {lines[end][2]}: bad indentation")
    if not isinstance(value, dict):
        raise InputError(f"calibration file {path}: expected keys, got a list")
    return value


def _balanced(text: str) -> bool:
    return text.count("[") + text.count("{") <= text.count("]") + text.count("}")


def _block(lines, i, indent, path):
    """The block value starting at line ``i`` with ``indent``: a sequence or a mapping."""
    if lines[i][1].startswith("- ") or lines[i][1] == "-":
        items = []
        while i < len(lines) and lines[i][0] == indent and lines[i][1].startswith("-"):
            items.append(_flow(_untag(lines[i][1][1:]), path, lines[i][2]))
            i += 1
        return items, i
    mapping, seen = {}, {}
    while i < len(lines) and lines[i][0] == indent:
        _, content, number = lines[i]
        key, sep, rest = content.partition(":")
        if not sep or (rest and not rest[0].isspace()):
            raise InputError(f"calibration file {path} line {number}: expected key: value, got "
                             f"{content[:40]!r}")
        key, rest = scalar(key) if key.strip()[:1] in "'\"" else key.strip(), _untag(rest)
        if key in seen:
            raise InputError(f"calibration file {path} line {number}: {key} given twice "
                             f"(lines {seen[key]} and {number})")
        seen[key] = number
        i += 1
        if rest:
            mapping[key] = _flow(rest, path, number)
        elif i < len(lines) and (lines[i][0] > indent or
                                 (lines[i][0] == indent and lines[i][1].startswith("-"))):
            mapping[key], i = _block(lines, i, lines[i][0], path)
        else:
            mapping[key] = None
    if i < len(lines) and lines[i][0] > indent:
        raise InputError(f"calibration file {path} line {lines[i][2]}: bad indentation")
    return mapping, i


def _children(node, path: Path) -> dict:
    """Tag -> value of an XML element's children; a tag given twice is refused."""
    values = {}
    for child in node:
        if child.tag in values:
            raise InputError(f"calibration file {path}: <{child.tag}> given twice")
        values[child.tag] = _element(child, path)
    return values


def _element(node, path: Path):
    """The value of one XML element (module docstring)."""
    children = list(node)
    if node.get("type_id") == "opencv-matrix" or (children and all(
            child.tag in ("rows", "cols", "dt", "data") for child in children)):
        fields = {child.tag: (child.text or "").split() for child in children}
        value = {"rows": scalar(" ".join(fields.get("rows", []))),
                 "cols": scalar(" ".join(fields.get("cols", []))),
                 "dt": " ".join(fields.get("dt", []))}
        if "data" in fields:
            value["data"] = [scalar(word) for word in fields["data"]]
        return value
    if children:
        return _children(node, path)
    words = (node.text or "").split()
    values = [scalar(word) for word in words]
    if len(values) == 1:
        return values[0]
    if values and all(isinstance(v, (int, float)) for v in values):
        return values
    return (node.text or "").strip()


def parse_xml(text: str, path: Path) -> dict:
    """The keys of a FileStorage XML text (``<opencv_storage>``); ``InputError`` if not XML or
    an element holds one tag twice."""
    try:
        root = ElementTree.fromstring(text.encode("utf-8"))
    except ElementTree.ParseError as exc:
        raise InputError(f"calibration file {path} is not readable XML: {first_line(exc)}") from exc
    if root.tag != "opencv_storage":
        raise InputError(f"calibration file {path}: expected <opencv_storage>, got <{root.tag}>")
    return _children(root, path)


def read_filestorage(path: str | Path) -> dict:
    """The keys of a FileStorage file, YAML or XML told from its first characters."""
    path = Path(path)
    text = read_text(path).lstrip("\ufeff")
    head = text.lstrip()[:64]
    if head.startswith("<"):
        return parse_xml(text, path)
    return parse_yaml(text, path)
