"""The documentation (README.md and docs/*.md) says what the tree does.

- Every relative link and image of every page resolves to a file, and a link's ``#fragment`` into
  a page names one of that page's headings.
- Every ``python -m MODULE ...`` command shown in a fenced code block composes against its config
  without doing any work: a hydra app runs as ``python -m MODULE args... --cfg job --resolve``
  (hydra prints the composed config and exits), a module that is not a hydra app answers
  ``--help``. ``make dataset|train|eval|bench ARGS="..."`` lines are the same commands through
  make; any other make target must exist in the Makefile. A multirun (``-m``) composes its first
  and its last point of the sweep (hydra refuses ``--cfg`` together with ``-m``).
- docs/configuration.md is what ``scripts/config_reference.py`` writes from the settings
  dataclasses, and the README stays a front door of at most 200 lines.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MAKEFILE = ROOT / "Makefile"
#: The packages whose modules the pages may run with ``python -m`` (others, e.g. pytest, are
#: not this project's entry points and are left alone).
PACKAGES = ("nbv", "train")
#: make targets that run an entry point with ``$(ARGS)`` (see the Makefile).
MAKE_MODULES = {
    "dataset": "nbv.dataset",
    "train": "train",
    "eval": "nbv.eval",
    "bench": "nbv.bench",
}
#: Seconds one command may take to compose (a cold start imports torch, numba, open3d).
TIMEOUT = 120
README_MAX_LINES = 200

FENCE = re.compile(r"^\s*(```|~~~)")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE = re.compile(r"^\s*\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+\"[^\"]*\")?\s*$", re.M)
INLINE_CODE = re.compile(r"(`+)(?!`).*?(?<!`)\1")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
PYTHON = re.compile(r"(^|/)python(3(\.\d+)?)?$")
#: How a module is a hydra app: ``@hydra.main`` or ``main = command(...)`` of nbv.config.cli.
HYDRA_APP = re.compile(r"@hydra\.main\(|^\s*main\s*=\s*command\(", re.M)
IMPORTED_MAIN = re.compile(r"^from\s+([\w.]+)\s+import\s+(?:.*\b)?main\b", re.M)
FOR_LOOP = re.compile(r"^\s*for\s+(\w+)\s+in\s+(.+?)\s*;\s*do\s*$")
SHELL_OPERATORS = {";", "&&", "||", "|", "&", ">", ">>", "<", "2>", "2>&1"}
#: hydra's command-line flags that take a value.
VALUE_FLAGS = {"--config-name", "-cn", "--config-path", "-cp", "--config-dir", "-cd", "--info"}


def relative(path: Path) -> str:
    """A path relative to the repository root, for messages and test ids."""
    return path.relative_to(ROOT).as_posix()


def prose_and_blocks(text: str) -> tuple[list[str], list[list[tuple[int, str]]]]:
    """Split a markdown page into its prose lines (fenced blocks blanked, so line numbers hold)
    and its fenced code blocks, each a list of ``(line number, line)``."""
    prose: list[str] = []
    blocks: list[list[tuple[int, str]]] = []
    current: list[tuple[int, str]] | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        if FENCE.match(line):
            if current is None:
                current = []
            else:
                blocks.append(current)
                current = None
            prose.append("")
        elif current is not None:
            current.append((number, line))
            prose.append("")
        else:
            prose.append(line)
    return prose, blocks


# --- links ---------------------------------------------------------------------------------


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: markup and punctuation dropped, lower case, spaces to
    hyphens (``## `ig` variants: 2026`` -> ``ig-variants-2026``)."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link keeps its text
    text = re.sub(r"[`*]", "", text).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of a page's headings, duplicates numbered as GitHub numbers them."""
    prose, _ = prose_and_blocks(page.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out: set[str] = set()
    for line in prose:
        match = HEADING.match(line)
        if not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f"{base}-{count}")
    return out


@dataclass(frozen=True)
class Link:
    """A relative link of a page: where it is and what it points at."""

    page: Path
    line: int
    target: str

    @property
    def file(self) -> Path:
        """The file the link names (the page itself for a pure ``#anchor``)."""
        path = self.target.split("#", 1)[0]
        return self.page if not path else (self.page.parent / path).resolve()

    @property
    def fragment(self) -> str:
        """The ``#fragment`` of the link, without the ``#`` (empty when there is none)."""
        return self.target.split("#", 1)[1] if "#" in self.target else ""

    def __str__(self) -> str:
        """``page:line: target``, the test id and the message's prefix."""
        return f"{relative(self.page)}:{self.line}: {self.target}"


def links(page: Path) -> list[Link]:
    """Every relative link and image of a page, outside code (URLs and mailto left out)."""
    prose, _ = prose_and_blocks(page.read_text(encoding="utf-8"))
    found = []
    for number, line in enumerate(prose, start=1):
        line = INLINE_CODE.sub(lambda m: " " * len(m.group(0)), line)
        targets = [m.group(1) for m in LINK.finditer(line)]
        targets += [m.group(1) for m in REFERENCE.finditer(line)]
        for target in targets:
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target):  # http:, https:, mailto:, ...
                continue
            found.append(Link(page, number, target))
    return found


ALL_LINKS = [link for page in PAGES for link in links(page)]


def test_pages_have_links():
    """The link check sees the pages' links (a broken pattern would pass every page)."""
    readme = [link for link in ALL_LINKS if link.page.name == "README.md"]
    assert len(readme) >= 5, [str(link) for link in readme]
    assert any(link.target.endswith(".png") for link in readme), "the README shows no picture"


@pytest.mark.parametrize("link", [link for link in ALL_LINKS if link.target.split("#")[0]], ids=str)
def test_link_resolves(link: Link):
    """A relative link or image names a file of the tree, relative to its page."""
    assert link.file.is_file(), f"{link}: no such file {link.file}"


@pytest.mark.parametrize(
    "link", [link for link in ALL_LINKS if link.fragment and link.file.suffix == ".md"], ids=str
)
def test_link_anchor_exists(link: Link):
    """A ``#fragment`` into a markdown page names one of its headings."""
    if not link.file.is_file():
        pytest.skip("the file itself is missing (test_link_resolves says so)")
    assert link.fragment in anchors(link.file), (
        f"{link}: {relative(link.file)} has no heading with the anchor #{link.fragment}"
    )


# --- commands ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Command:
    """A ``python -m`` command of a page, as the test runs it."""

    module: str
    args: tuple[str, ...]
    where: str

    @property
    def id(self) -> str:
        """The test id: where the command is first shown, and its module."""
        return f"{self.where} {self.module}"


def logical_lines(block: list[tuple[int, str]]) -> list[tuple[int, str]]:
    """The block's shell lines: continuations (``\\``) joined, ``$ `` prompts stripped,
    comment lines and blank lines dropped; each with the line number it starts on."""
    out: list[tuple[int, str]] = []
    pending: tuple[int, str] | None = None
    for number, raw in block:
        line = raw.rstrip()
        if pending is not None:
            start, text = pending
            line, number = text + " " + line.lstrip(), start
            pending = None
        if line.endswith("\\"):
            pending = (number, line[:-1].rstrip())
            continue
        line = re.sub(r"^\s*\$\s+", "", line).strip()
        if line and not line.startswith("#"):
            out.append((number, line))
    if pending is not None:
        out.append(pending)
    return out


def expand_variables(tokens: list[str], variables: dict[str, str]) -> list[str]:
    """Shell variables of an enclosing ``for`` loop replaced by the loop's first value."""

    def one(token: str) -> str:
        for name, value in variables.items():
            token = re.sub(rf"\$(\{{{name}\}}|{name}\b)", value, token)
        return token

    return [one(token) for token in tokens]


def commands_of(page: Path) -> tuple[list[Command], list[tuple[str, str]]]:
    """The page's ``python -m`` commands of this project (``make`` lines mapped to theirs), and
    the ``(where, target)`` of every other make line."""
    _, blocks = prose_and_blocks(page.read_text(encoding="utf-8"))
    commands: list[Command] = []
    targets: list[tuple[str, str]] = []
    for block in blocks:
        variables: dict[str, str] = {}
        for number, line in logical_lines(block):
            where = f"{relative(page)}:{number}"
            loop = FOR_LOOP.match(line)
            if loop:
                variables[loop.group(1)] = shlex.split(loop.group(2))[0]
                continue
            try:
                tokens = expand_variables(shlex.split(line, comments=True), variables)
            except ValueError:  # not shell (a file layout, JSON): no command here
                continue
            command = python_command(tokens, where) or make_command(tokens, where, targets)
            if command is not None:
                commands.append(command)
    return commands, targets


def python_command(tokens: list[str], where: str) -> Command | None:
    """``[ENV=...] .../python -m MODULE args...`` -> its Command (None for other lines and for
    modules outside this project)."""
    for i in range(len(tokens) - 2):
        if PYTHON.search(tokens[i]) and tokens[i + 1] == "-m":
            module = tokens[i + 2]
            if module.split(".")[0] not in PACKAGES:
                return None
            args = []
            for token in tokens[i + 3 :]:
                if token in SHELL_OPERATORS:
                    break
                args.append(token)
            return Command(module, tuple(args), where)
    return None


def make_command(tokens: list[str], where: str, targets: list[tuple[str, str]]) -> Command | None:
    """``make TARGET [ARGS="..."]``: the entry point's Command for the targets that run one;
    other targets are noted in ``targets``."""
    if len(tokens) < 2 or tokens[0] != "make":
        return None
    target = tokens[1]
    args = [t.split("=", 1)[1] for t in tokens[2:] if t.startswith("ARGS=")]
    if target in MAKE_MODULES:
        return Command(MAKE_MODULES[target], tuple(shlex.split(" ".join(args))), where)
    targets.append((where, target))
    return None


def module_source(module: str) -> Path | None:
    """The file ``python -m module`` runs: ``a/b.py`` or ``a/b/__main__.py`` (None if neither)."""
    base = ROOT.joinpath(*module.split("."))
    for path in (base.with_suffix(".py"), base / "__main__.py"):
        if path.is_file():
            return path
    return None


def is_hydra_app(module: str) -> bool:
    """Whether the module's ``main`` is a hydra app (following a ``from X import main``)."""
    path = module_source(module)
    while path is not None:
        text = path.read_text(encoding="utf-8")
        if HYDRA_APP.search(text):
            return True
        imported = IMPORTED_MAIN.search(text)
        path = module_source(imported.group(1)) if imported else None
    return False


def gather() -> tuple[list[Command], list[tuple[str, str]]]:
    """Every page's commands, each distinct one once (at its first place), and the make lines."""
    seen: dict[tuple[str, tuple[str, ...]], Command] = {}
    targets: list[tuple[str, str]] = []
    for page in PAGES:
        commands, page_targets = commands_of(page)
        targets += page_targets
        for command in commands:
            # A tool that is not a hydra app answers --help whatever its arguments: once.
            args = command.args if is_hydra_app(command.module) else ()
            seen.setdefault((command.module, args), command)
    return list(seen.values()), targets


COMMANDS, MAKE_TARGETS = gather()


def sweep_points(args: tuple[str, ...]) -> list[list[str]]:
    """A multirun's arguments as the commands hydra can compose one by one: every sweep at its
    first value, then at its last. Without ``-m`` the arguments themselves."""
    if not {"-m", "--multirun"} & set(args):
        return [list(args)]
    from hydra.core.override_parser.overrides_parser import OverridesParser

    flags: list[str] = []
    lines: list[str] = []
    rest = iter(a for a in args if a not in ("-m", "--multirun"))
    for arg in rest:
        if arg in VALUE_FLAGS:
            flags += [arg, next(rest)]
        elif arg.startswith("-"):
            flags.append(arg)
        else:
            lines.append(arg)
    points: list[list[str]] = [list(flags), list(flags)]
    for override in OverridesParser.create().parse_overrides(lines):
        if override.is_sweep_override():
            values = list(override.sweep_string_iterator())
            key = override.get_key_element()
            picks = [f"{key}={values[0]}", f"{key}={values[-1]}"]
        else:
            picks = [override.input_line, override.input_line]
        for point, pick in zip(points, picks, strict=True):
            point.append(pick)
    return points if points[0] != points[1] else points[:1]


def test_commands_found():
    """The command check sees the pages' commands, and each page with a ``python -m`` example in
    a code block has it checked (a broken parser would pass everything)."""
    modules = {c.module for c in COMMANDS}
    assert {"nbv.dataset", "train", "nbv.eval", "nbv.plan"} <= modules, sorted(modules)
    assert len(COMMANDS) < 60, f"{len(COMMANDS)} distinct commands: keep the test fast"


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c.id)
@pytest.mark.slow
def test_command_composes(command: Command):
    """A shown command composes against its config (a hydra app) or answers ``--help``."""
    assert module_source(command.module) is not None, (
        f"{command.where}: python -m {command.module}: no such module in the tree"
    )
    if is_hydra_app(command.module):
        runs = [[*point, "--cfg", "job", "--resolve"] for point in sweep_points(command.args)]
    else:
        runs = [["--help"]]
    for extra in runs:
        argv = [sys.executable, "-m", command.module, *extra]
        done = subprocess.run(
            argv, cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT, check=False
        )
        shown = shlex.join(["python", "-m", command.module, *extra])
        assert done.returncode == 0, (
            f"{command.where}: `{shown}` exited with {done.returncode}:\n{done.stderr[-2000:]}"
        )


@pytest.mark.parametrize(
    "where, target", MAKE_TARGETS, ids=[f"{w} make {t}" for w, t in MAKE_TARGETS]
)
def test_make_target_exists(where: str, target: str):
    """A ``make`` target a page shows is a target of the Makefile."""
    defined = re.findall(r"^([\w.-]+)\s*:", MAKEFILE.read_text(encoding="utf-8"), re.M)
    assert target in defined, f"{where}: make {target}: no such target (Makefile: {defined})"


# --- pages ---------------------------------------------------------------------------------


def test_readme_is_short():
    """The README is the front door; what a reader looks up lives under docs/."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, f"README.md has {lines} lines (at most {README_MAX_LINES})"


def entry_points() -> set[str]:
    """Every module of nbv/ and train/ that runs as ``python -m``: a ``__main__.py`` or a module
    with an ``if __name__ == "__main__":`` block."""
    found = set()
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            if re.search(r'^if __name__ == "__main__":', path.read_text(encoding="utf-8"), re.M):
                parts = path.relative_to(ROOT).with_suffix("").parts
                found.add(".".join(parts[:-1] if parts[-1] == "__main__" else parts))
    return found


def test_readme_shows_every_entry_point():
    """The README gives one example per entry point (directly or through make)."""
    commands, _ = commands_of(ROOT / "README.md")
    shown = {command.module for command in commands}
    missing = sorted(entry_points() - shown)
    assert not missing, f"README.md shows no example of: {', '.join(missing)}"


@pytest.mark.slow
def test_configuration_reference_is_current():
    """docs/configuration.md is what ``scripts/config_reference.py`` writes now."""
    script = ROOT / "scripts" / "config_reference.py"
    done = subprocess.run(
        [sys.executable, str(script), "--check"],
        cwd=ROOT, capture_output=True, text=True, timeout=TIMEOUT, check=False,
    )  # fmt: skip
    assert done.returncode == 0, (
        "docs/configuration.md is out of date: run `.venv/bin/python scripts/config_reference.py`"
        f"\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
    )
