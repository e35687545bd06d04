"""What the generated doc pages (docs/api.md, docs/kernels.md) share: the diff from the checked-in page to the
page as generated now, and the command line that writes the page or checks that it is current (--check)."""
from __future__ import annotations

import argparse
import difflib
import sys
from pathlib import Path
from typing import Callable


def diff(path: Path, generated: str) -> list[str]:
    """The unified diff from ``path`` to ``generated``: empty when the page is up to date."""
    current = path.read_text(encoding="utf-8") if path.exists() else ""
    return list(difflib.unified_diff(current.splitlines(keepends=True), generated.splitlines(keepends=True),
                                     fromfile=str(path), tofile="generated"))


def main(argv: list[str] | None, description: str, root: Path, page: Path, render: Callable[[], str],
         tool: str) -> int:
    """Write ``page`` from ``render()``, or with --check exit 1 (printing the diff) if it is out of date; ``tool``
    is the command that regenerates it (for the message)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--check", action="store_true", help=f"exit 1 if {page.relative_to(root)} is out of date")
    args = parser.parse_args(argv)
    if args.check:
        changes = diff(page, render())
        if changes:
            sys.stdout.writelines(changes)
            print(f"\n{page.relative_to(root)} is out of date: run python tools/{tool}")
            return 1
        print(f"{page.relative_to(root)} is up to date")
        return 0
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(render(), encoding="utf-8")
    print(f"wrote {page.relative_to(root)}")
    return 0
