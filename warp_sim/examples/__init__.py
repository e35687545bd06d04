"""The example stages, shipped inside the package so that a pip install has them too.

``names()`` lists them, ``path(name)`` is one's absolute path (to read: the installed copy may not be writable),
``copy(name, folder)`` writes one, with every file it references, into a folder of one's own. The same from the
command line: ``warp-sim example NAME --out DIR``.
"""
from __future__ import annotations

import filecmp
import pathlib
import shutil

from pxr import Sdf, UsdUtils

#: the folder holding the example stages (this package's own)
FOLDER = pathlib.Path(__file__).resolve().parent
#: what an example stage's file name ends in
EXTENSIONS = (".usda", ".usdc", ".usd")


def names() -> list[str]:
    """The example stages' file names, sorted, e.g. ``["tabletop_cm.usda"]``."""
    return sorted(item.name for item in FOLDER.iterdir() if item.is_file() and item.suffix in EXTENSIONS)


def path(name: str) -> str:
    """The absolute path of the example stage ``name`` (one of ``names()``); a ValueError names the others."""
    if not isinstance(name, str) or name not in names():
        raise ValueError(f"name={name!r} is invalid: expected one of {', '.join(names())} (ws.examples.names())")
    return str(FOLDER / name)


def files(name: str) -> list[str]:
    """The example ``name`` and every file it reads (sublayers, references, payloads, assets), as paths relative
    to FOLDER, the stage first."""
    layers, assets, _ = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(path(name)))
    found = [pathlib.Path(layer.realPath) for layer in layers] + [pathlib.Path(asset) for asset in assets]
    relative = [str(item.resolve().relative_to(FOLDER)) for item in found if item.resolve().is_relative_to(FOLDER)]
    return [name] + sorted(set(relative) - {name})


def copy(name: str, folder) -> str:
    """Copy the example stage ``name`` and the files it reads into ``folder`` (made if missing), at the same
    relative paths, so that it opens there as here; returns the stage's new path. A file already there is kept
    when it is the same, and a ValueError naming ``folder`` when it differs (nothing is overwritten)."""
    target = pathlib.Path(folder)
    if target.exists() and not target.is_dir():
        raise ValueError(f"folder={str(folder)!r} is invalid: it is an existing file; expected a folder")
    pairs = [(FOLDER / item, target / item) for item in files(name)]
    clash = [str(there) for here, there in pairs if there.exists() and not filecmp.cmp(here, there, shallow=False)]
    if clash:
        raise ValueError(f"folder={str(folder)!r} is invalid: {', '.join(clash)} exists and differs from the "
                         f"example; remove it or give another folder")
    for here, there in pairs:
        there.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(here, there)
    return str(pairs[0][1])
