"""Every fenced code block of ``README.md`` and ``docs/python-api.md`` runs in the suite, so that
the examples cannot drift from the code (issue 72, item 11).

- `` ```python `` blocks are executed with ``exec``, in the order of the document, all blocks of
  one document in one namespace (a later block uses the names of an earlier one), in a new
  empty working directory (the files they write land there). They run as written: an example
  that is too slow for the suite is made cheaper in the document (a crop of scikit-image's
  Motorcycle pair, the same crop, ``ndisp`` and plans in both documents, so that the graphs
  compile once), not skipped here.
- `` ```bash `` and `` ```sh `` blocks: every command of every line (backslash continuations
  joined, ``&&`` chains split, comments dropped) is one of

  * ``sswjax ...``: parsed by the command line's own parser (:func:`sswjax.cli.app.build_parser`,
    ``parse_args`` only: nothing runs) after the placeholders of :data:`PLACEHOLDERS` are
    replaced by real small files, so a documented option that does not exist, a value its
    option refuses or a preset that is not one fails the test;
  * ``NAME=VALUE``: a shell variable that the block's later lines use as ``$NAME``;
  * a command of :data:`SKIPPED` (installing, the suite itself), named there with the reason;

  anything else fails.
- `` ```text `` blocks are text on purpose (a synopsis, an output): nothing runs, but every
  ``--option`` of a line ``sswjax COMMAND ...`` (and of its indented continuation lines) must
  be an option of that command.
- A fence with no language or another one fails: no block is skipped silently.

And every relative link of ``README.md`` and ``docs/**/*.md`` (``[text](path)``, images too,
outside code) points to a file or folder that exists (issue 70, item 4: pages move to
``docs/notes/`` without leaving links behind).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
from pathlib import Path
from typing import NamedTuple

import imageio.v3 as iio
import numpy as np
import pytest

from sswjax.cli.app import build_parser

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = ("README.md", "docs/python-api.md")
"""The documents whose every code block runs, relative to the repository's root."""

LANGUAGES = ("python", "bash", "sh", "text")
"""The fences this test knows; any other fails :func:`test_every_block_has_a_known_language`."""

SKIPPED = {
    ("python3", "-m", "venv"): "creates the environment this suite already runs in",
    (".", ".venv/bin/activate"): "activates that environment",
    ("pip", "install"): "installs the package this suite already imports",
    ("python", "-m", "pytest"): "runs this suite",
}
"""Commands of the shell blocks that are not checked, each by its first words, and why."""

PLACEHOLDERS = {
    "LEFT": "left.png",
    "RIGHT": "right.png",
    "N": "16",
    "OUT.pfm": "out.pfm",
}
"""Placeholder words of the shell blocks and what replaces them: a small file that
:func:`workdir`, the commands' working directory, holds (``im0.png``, ``im1.png`` and
``calib.txt`` too), or a value."""

_FENCE = re.compile(r"^(?P<indent> *)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")
_VARIABLE = re.compile(r"\$\{?([A-Za-z_]\w*)\}?")
_OPTION = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


class Block(NamedTuple):
    """One fenced code block: its language (the info string's first word, ``""`` for none),
    the 1-based line of its opening fence and its text."""

    language: str
    line: int
    text: str


def code_blocks(markdown: str) -> list[Block]:
    """The fenced code blocks of a Markdown text, in order (CommonMark's fences: three or more
    backticks or tildes, closed by at least as many of the same character)."""
    blocks, lines, index = [], markdown.splitlines(), 0
    while index < len(lines):
        opening = _FENCE.match(lines[index])
        if opening is None:
            index += 1
            continue
        fence, indent = opening["fence"], len(opening["indent"])
        info = opening["info"].strip()
        words = info.split()
        body, end = [], index + 1
        while end < len(lines):
            closing = _FENCE.match(lines[end])
            if closing and closing["fence"][0] == fence[0] and len(closing["fence"]) >= len(fence) \
                    and not closing["info"].strip():
                break
            body.append(lines[end][indent:] if lines[end][:indent].isspace() else lines[end])
            end += 1
        blocks.append(Block(words[0] if words else "", index + 1, "\n".join(body) + "\n"))
        index = end + 1
    return blocks


def unknown_languages(markdown: str) -> list[str]:
    """``line N: <language>`` of every block whose language is not one of :data:`LANGUAGES`."""
    return [f"line {block.line}: {block.language or '(none)'}" for block in code_blocks(markdown)
            if block.language not in LANGUAGES]


def shell_commands(text: str) -> list[tuple[int, list[str]]]:
    """``(line offset, words)`` of every command of a shell block: continuations joined,
    comments dropped, ``&&``, ``||`` and ``;`` chains split (offset 0 = the block's first line)."""
    commands, pending, start = [], "", 0
    for offset, line in enumerate(text.splitlines()):
        if not pending:
            start = offset
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        words = shlex.split(pending + line, comments=True)
        pending = ""
        command: list[str] = []
        for word in words + [";"]:
            if word in ("&&", "||", ";"):
                if command:
                    commands.append((start, command))
                command = []
            else:
                command.append(word)
    assert not pending, "a shell block ends with a backslash continuation"
    return commands


def _where(document: str, block: Block, offset: int = 0) -> str:
    return f"{document}:{block.line + 1 + offset}"


def _blocks(document: str, *languages: str) -> list[Block]:
    return [block for block in code_blocks((ROOT / document).read_text(encoding="utf-8"))
            if block.language in languages]


@pytest.fixture(scope="module")
def parser() -> argparse.ArgumentParser:
    """The command line's parser with every command (built once: each command's module is
    imported)."""
    return build_parser()


@pytest.fixture()
def workdir(tmp_path, monkeypatch, texture) -> Path:
    """A new working directory holding a small pair (``left.png``, ``right.png``, ``im0.png``,
    ``im1.png``, 24x40, disparity 3) and a Middlebury ``calib.txt``; the test runs in it."""
    right = texture(0)
    left = np.roll(right, 3, axis=1)
    for name, image in (("left.png", left), ("right.png", right), ("im0.png", left),
                        ("im1.png", right)):
        iio.imwrite(tmp_path / name, image)
    (tmp_path / "calib.txt").write_text("cam0=[500 0 20; 0 500 12; 0 0 1]\ndoffs=0\n"
                                        "baseline=100\nwidth=40\nheight=24\nndisp=16\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("document", DOCUMENTS)
def test_every_block_has_a_known_language(document):
    markdown = (ROOT / document).read_text(encoding="utf-8")
    assert code_blocks(markdown), f"{document} has no code block"
    assert unknown_languages(markdown) == [], (
        f"{document}: code blocks fenced with a language this test does not run "
        f"(one of {', '.join(LANGUAGES)}; ```text for text on purpose)")


def test_an_unknown_or_missing_language_is_found():
    """The check above can fail: a block without a language, or with one this test does not
    run, is named with its line; fences of tildes and longer fences count too."""
    markdown = ("# t\n\n```python\nx = 1\n```\n\n```\nplain\n```\n\n~~~js\nlet x\n~~~\n\n"
                "````text\n```\nnested\n```\n````\n")
    assert [(b.language, b.line) for b in code_blocks(markdown)] == [
        ("python", 3), ("", 7), ("js", 11), ("text", 15)]
    assert unknown_languages(markdown) == ["line 7: (none)", "line 11: js"]


def test_shell_lines_split_into_commands():
    text = ("python3 -m venv .venv && . .venv/bin/activate   # comment && not a command\n"
            "sswjax match a b \\\n    --ndisp 8 -o d.pfm\n")
    assert shell_commands(text) == [
        (0, ["python3", "-m", "venv", ".venv"]), (0, [".", ".venv/bin/activate"]),
        (1, ["sswjax", "match", "a", "b", "--ndisp", "8", "-o", "d.pfm"])]


def test_python_blocks_run(tmp_path, monkeypatch):
    """Both documents in one test, so that one process compiles the graphs they share (the
    same crop, ``ndisp`` and presets) once; each document in a namespace and an empty working
    directory of its own (an example reads only the files it writes)."""
    for number, document in enumerate(DOCUMENTS):
        blocks = _blocks(document, "python")
        assert blocks, f"{document} has no python block"
        workdir = tmp_path / str(number)
        workdir.mkdir()
        monkeypatch.chdir(workdir)
        namespace: dict = {"__name__": "__docs_example__"}
        path = str(ROOT / document)
        for block in blocks:
            # Blank lines before the code: tracebacks give the document's own line numbers.
            code = compile("\n" * block.line + block.text, path, "exec")
            try:
                exec(code, namespace)  # noqa: S102 (the documented example, on purpose)
            except Exception as error:
                error.add_note(f"in the python block of {_where(document, block, -1)}")
                raise


@pytest.mark.parametrize("document", DOCUMENTS)
def test_shell_blocks_parse(document, workdir, parser):
    checked = 0
    for block in _blocks(document, "bash", "sh"):
        variables: dict[str, str] = {}
        for offset, words in shell_commands(block.text):
            where = _where(document, block, offset)
            if len(words) == 1 and re.fullmatch(r"[A-Za-z_]\w*=.*", words[0]):
                name, value = words[0].split("=", 1)
                variables[name] = value
                continue
            unset = {name for word in words for name in _VARIABLE.findall(word)} - set(variables)
            assert not unset, f"{where}: ${', $'.join(sorted(unset))} set nowhere in the block"
            words = [_VARIABLE.sub(lambda m: variables[m[1]], word) for word in words]
            if any(tuple(words[:len(prefix)]) == prefix for prefix in SKIPPED):
                continue
            assert words[0] == "sswjax", (
                f"{where}: {shlex.join(words)!r} is neither an sswjax command nor one of the "
                "skipped commands of this test (SKIPPED)")
            argv = [PLACEHOLDERS.get(word, word) for word in words[1:]]  # files: in workdir
            stderr = io.StringIO()
            with contextlib.redirect_stderr(stderr):
                try:
                    parser.parse_args(argv)
                except SystemExit as exit_:
                    pytest.fail(f"{where}: {shlex.join(words)!r} does not parse (exit "
                                f"{exit_.code}): {stderr.getvalue().strip()}")
            checked += 1
    if document == "README.md":
        assert checked, "README.md documents no sswjax command in a bash block"


def _options(parser: argparse.ArgumentParser, command: str) -> set[str]:
    """The option strings of ``sswjax`` itself and of its sub-command ``command``."""
    commands = next(action for action in parser._actions
                    if isinstance(action, argparse._SubParsersAction))
    assert command in commands.choices, f"no command {command!r}"
    return {option for level in (parser, commands.choices[command]) for action in level._actions
            for option in action.option_strings}


@pytest.mark.parametrize("document", DOCUMENTS)
def test_text_blocks_name_existing_options(document, parser):
    for block in _blocks(document, "text"):
        command = None
        for offset, line in enumerate(block.text.splitlines()):
            words = line.split()
            if words[:1] == ["sswjax"] and len(words) > 1:
                command = words[1]
            elif not line[:1].isspace():
                command = None  # not a continuation of a synopsis line
            if command is None:
                continue
            unknown = sorted(set(_OPTION.findall(line)) - _options(parser, command))
            assert not unknown, (f"{_where(document, block, offset)}: sswjax {command} has no "
                                 f"option {', '.join(unknown)}")


_LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_INLINE_CODE = re.compile(r"(`+).+?\1", re.DOTALL)


def relative_links(markdown: str) -> list[str]:
    """The targets of a Markdown text's relative links and images, outside fenced blocks and
    inline code, without their ``#anchor``: web and mail addresses and links within the page
    (``#anchor`` alone) are left out."""
    lines, inside = [], None
    for line in markdown.splitlines():
        fence = _FENCE.match(line)
        if fence and (inside is None or (fence["fence"][0] == inside[0]
                                         and len(fence["fence"]) >= len(inside))):
            inside = fence["fence"] if inside is None else None
            continue
        if inside is None:
            lines.append(line)
    text = _INLINE_CODE.sub("", "\n".join(lines))
    targets = [target.split("#", 1)[0] for target in _LINK.findall(text)]
    return [t for t in targets if t and not re.match(r"[a-z][a-z0-9+.-]*:", t, re.IGNORECASE)]


def test_relative_links_are_found():
    markdown = ("See [a](docs/a.md#x), ![b](img/b.png \"title\"), [c](https://x.org/c.md), "
                "[d](#local) and `[e](not/a/link.md)`.\n\n```text\n[f](in/a/block.md)\n```\n")
    assert relative_links(markdown) == ["docs/a.md", "img/b.png"]


def test_every_relative_link_of_the_docs_points_to_a_file():
    documents = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    broken = [f"{document.relative_to(ROOT)}: {target}" for document in documents
              for target in relative_links(document.read_text(encoding="utf-8"))
              if not (document.parent / target).exists()]
    assert broken == [], "links to files that do not exist:\n" + "\n".join(broken)
