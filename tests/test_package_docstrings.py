"""Every package's docstring is true: it names each of its modules and lists exactly the
third-party packages its modules import (``Third-party imports: ...``, its last line)."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = sorted(p.parent for p in (ROOT / "nbv").glob("*/__init__.py")) + [ROOT / "train"]
FIRST_PARTY = {"nbv", "train", "__future__"}


def _docstring(package: Path) -> str:
    return ast.get_docstring(ast.parse((package / "__init__.py").read_text())) or ""


def _modules(package: Path) -> list[str]:
    return sorted(p.stem for p in package.glob("*.py") if p.stem not in ("__init__", "__main__"))


def _imported(package: Path) -> set[str]:
    """The top-level names of every import in the package's modules outside the standard
    library and this project (imports inside functions included)."""
    found = set()
    for path in package.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            found |= {n.split(".")[0] for n in names}
    return found - set(sys.stdlib_module_names) - FIRST_PARTY


@pytest.mark.parametrize("package", PACKAGES, ids=[p.name for p in PACKAGES])
def test_a_package_docstring_names_its_modules_and_imports(package):
    doc = _docstring(package)
    name = ".".join(package.relative_to(ROOT).parts)
    unnamed = [m for m in _modules(package) if f"{name}.{m}" not in doc]
    assert not unnamed, f"{name}'s docstring does not name {unnamed}"
    stated = re.search(r"Third-party imports: (.*)\.\s*$", doc)
    assert stated, f"{name}'s docstring does not end with its third-party imports"
    listed = set() if stated.group(1) == "none" else set(stated.group(1).split(", "))
    assert listed == _imported(package), name
