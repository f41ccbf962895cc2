"""Compare two runs of the toolkit for exact equality: HDF5 files, checkpoints, evaluation results.

Used to show that a refactoring changed no output:

    python scripts/compare_runs.py h5 BEFORE_DIR AFTER_DIR        # every *.h5, datasets and attrs
    python scripts/compare_runs.py ckpt BEFORE.pt AFTER.pt        # every weight tensor
    python scripts/compare_runs.py results BEFORE.json AFTER.json # every episode's views and curves
    python scripts/compare_runs.py all BEFORE_DIR AFTER_DIR       # all three, every file of a tree
    python scripts/compare_runs.py files BEFORE_DIR AFTER_DIR     # every file, byte for byte
    python scripts/compare_runs.py plan BEFORE.json AFTER.json    # a plan.json, timings aside

(``scripts/reference_outputs.sh`` makes such a tree.)

Prints one line per compared item and exits 1 when anything differs. Attributes that record
the settings as JSON (``config``) are compared as parsed JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def _h5_items(path: Path) -> dict[str, tuple[str, object]]:
    """Every dataset and attribute of an HDF5 file: name -> (kind, value)."""
    import h5py

    items: dict[str, tuple[str, object]] = {}

    def attrs(name: str, obj) -> None:
        for key, value in obj.attrs.items():
            items[f"{name}@{key}"] = ("attr", value)

    with h5py.File(path, "r") as f:
        attrs("/", f)

        def visit(name: str, obj) -> None:
            attrs(name, obj)
            if isinstance(obj, h5py.Dataset):
                items[name] = ("data", obj[()])

        f.visititems(visit)
    return items


def _equal(a: object, b: object) -> bool:
    if isinstance(a, str | bytes) and isinstance(b, str | bytes):
        try:
            return json.loads(a) == json.loads(b)
        except (ValueError, TypeError):
            return a == b
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))


def compare_h5(before: Path, after: Path) -> list[str]:
    """Differences between the ``*.h5`` files of two folders (names relative to the folders)."""
    problems = []
    names_b = sorted(p.relative_to(before) for p in before.rglob("*.h5"))
    names_a = sorted(p.relative_to(after) for p in after.rglob("*.h5"))
    if names_b != names_a:
        problems.append(f"file lists differ: {names_b} vs {names_a}")
    for name in sorted(set(names_b) & set(names_a)):
        ib, ia = _h5_items(before / name), _h5_items(after / name)
        if set(ib) != set(ia):
            problems.append(f"{name}: keys differ: {sorted(set(ib) ^ set(ia))}")
        bad = [k for k in sorted(set(ib) & set(ia)) if not _equal(ib[k][1], ia[k][1])]
        problems += [f"{name}: {k} differs" for k in bad]
        print(f"{name}: {len(ib)} datasets and attributes, {len(bad)} differ")
    return problems


def compare_ckpt(before: Path, after: Path) -> list[str]:
    """Differences between the weights (and optimizer state) of two checkpoints."""
    import torch

    b = torch.load(before, map_location="cpu", weights_only=False)
    a = torch.load(after, map_location="cpu", weights_only=False)
    sb, sa = b["state_dict"], a["state_dict"]
    problems = [] if set(sb) == set(sa) else [f"weight names differ: {set(sb) ^ set(sa)}"]
    bad = [k for k in sb if k in sa and not torch.equal(sb[k], sa[k])]
    problems += [f"weight {k} differs" for k in bad]
    print(f"{before}: {len(sb)} tensors, {len(bad)} differ")
    return problems


def compare_results(before: Path, after: Path) -> list[str]:
    """Differences between the episodes (views, coverage, VIG, AUC) of two results.json."""
    fields = ("dataset", "viewspace", "method", "check", "key", "category", "start", "views",
              "coverage", "vig", "auc")  # fmt: skip
    b = json.loads(before.read_text())["episodes"]
    a = json.loads(after.read_text())["episodes"]
    if len(b) != len(a):
        return [f"episode counts differ: {len(b)} vs {len(a)}"]
    problems = []
    for i, (eb, ea) in enumerate(zip(b, a, strict=True)):
        for key in fields:
            if eb.get(key) != ea.get(key):
                problems.append(f"episode {i} ({eb.get('method')}, {eb.get('key')}): {key}")
    print(f"{before}: {len(b)} episodes, {len(problems)} fields differ")
    return problems


def compare_files(before: Path, after: Path) -> list[str]:
    """Files of two trees that differ byte for byte, or exist in only one (JSON files compared
    parsed, without the keys that hold wall-clock times or dates; logs, which hold times, left
    out)."""
    names_b = {p.relative_to(before) for p in before.rglob("*") if p.is_file()}
    names_a = {p.relative_to(after) for p in after.rglob("*") if p.is_file()}
    names_b = {n for n in names_b if n.suffix != ".log"}
    names_a = {n for n in names_a if n.suffix != ".log"}
    problems = [f"{name}: only in one tree" for name in sorted(names_b ^ names_a)]
    for name in sorted(names_b & names_a):
        b, a = before / name, after / name
        if name.suffix == ".json":
            problems += [f"{name}: {line}" for line in compare_plan(b, a)]
        elif b.read_bytes() != a.read_bytes():
            problems.append(f"{name}: differs")
    print(f"{before}: {len(names_b)} files, {len(problems)} differ")
    return problems


def _untimed(value: object) -> object:
    """A parsed JSON value without the keys that record times (they differ between runs)."""
    if isinstance(value, dict):
        return {
            k: _untimed(v)
            for k, v in value.items()
            if not any(word in k for word in ("time", "timing", "seconds", "date", "created"))
        }
    if isinstance(value, list):
        return [_untimed(v) for v in value]
    return value


def compare_plan(before: Path, after: Path) -> list[str]:
    """Differences between two JSON files (a ``plan.json``, a manifest), timings aside."""
    b = _untimed(json.loads(before.read_text()))
    a = _untimed(json.loads(after.read_text()))
    if b == a:
        return []
    keys = sorted(set(b) | set(a)) if isinstance(b, dict) and isinstance(a, dict) else [""]
    return [f"{before.name}: {k} differs" for k in keys if k == "" or b.get(k) != a.get(k)]


def compare_all(before: Path, after: Path) -> list[str]:
    """Every HDF5 file, checkpoint and ``results.json`` of two trees, matched by relative path."""
    problems = compare_h5(before, after)
    for pattern, compare in (("*.pt", compare_ckpt), ("results.json", compare_results)):
        names = sorted(p.relative_to(before) for p in before.rglob(pattern))
        if not names:
            problems.append(f"no {pattern} under {before}")
        for name in names:
            if not (after / name).exists():
                problems.append(f"{name}: missing under {after}")
                continue
            problems += [f"{name}: {line}" for line in compare(before / name, after / name)]
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=("h5", "ckpt", "results", "all", "files", "plan"))
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    kinds = {
        "h5": compare_h5,
        "ckpt": compare_ckpt,
        "results": compare_results,
        "all": compare_all,
        "files": compare_files,
        "plan": compare_plan,
    }
    compare = kinds[args.kind]
    problems = compare(args.before, args.after)
    for line in problems:
        print("DIFF", line)
    print("equal" if not problems else f"{len(problems)} differences")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
