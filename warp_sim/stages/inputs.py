"""The files a run reads, so that its output never overwrites one of them.

A run over an input stage (``run(..., over=stage)``, ``warp-sim run SCENE --out OUT``) reads that stage's whole
layer stack: its root layer, its sublayers (recursively), the layers of its references and payloads (variants'
too), value clips and asset-valued attributes, as ``UsdUtils.ComputeAllDependencies`` finds them; a reference to
a file that does not exist yet counts too (anchored at the layer that names it), since the overlay would read it
once it is written. An output path is matched against them by real path (``os.path.realpath``: ``./t.usda``, an
absolute path and a symlink are the same file) and, where both exist, by ``os.path.samefile`` (hard links).
"""
from __future__ import annotations

import os

from pxr import Usd, UsdUtils

__all__ = ["files_read", "overwrite_problem", "overwritten", "refuse_overwrite"]


def _roots(source) -> tuple[list[str], list]:
    """(file paths to follow, layers already open) of a stage or a path."""
    if isinstance(source, Usd.Stage):   # its root layer's file, or (in memory) the files of the layers it uses
        layers, root = list(source.GetUsedLayers()), source.GetRootLayer().realPath
        return [root] if root else [layer.realPath for layer in layers if layer.realPath], layers
    return [os.fspath(source)], []


def files_read(source) -> list[str]:
    """The real paths of every file that ``source`` (a stage's path or a Usd.Stage) reads, its root first."""
    roots, layers = _roots(source)
    found = dict.fromkeys(os.path.realpath(root) for root in roots)
    quiet = UsdUtils.CoalescingDiagnosticDelegate()   # a missing reference is the reader's to report, not ours
    try:
        for root in roots:
            dependencies, assets, unresolved = UsdUtils.ComputeAllDependencies(root)
            layers.extend(dependencies)
            found.update(dict.fromkeys(os.path.realpath(asset) for asset in assets))
            for layer in dependencies if unresolved else ():
                for named in layer.GetCompositionAssetDependencies():
                    if named in unresolved and layer.realPath:
                        found[os.path.realpath(os.path.join(os.path.dirname(layer.realPath), named))] = None
    finally:
        del quiet
    found.update(dict.fromkeys(os.path.realpath(layer.realPath) for layer in layers if layer.realPath))
    return list(found)


def overwritten(output, source) -> str | None:
    """The file of ``files_read(source)`` that writing ``output`` would replace (by real path, or the same file
    under another name), or None."""
    target = os.path.realpath(os.fspath(output))
    for path in files_read(source):
        if path == target:
            return path
        try:
            if os.path.samefile(path, target):
                return path
        except OSError:   # either is missing
            pass
    return None


def overwrite_problem(output, source, what: str) -> str | None:
    """Why writing ``output`` is refused, if it would replace a file that ``source`` (a stage's path or a
    Usd.Stage, named ``what`` in the message, e.g. "the input stage over='t.usda'") reads; else None."""
    hit = overwritten(output, source)
    if hit is None:
        return None
    roots = _roots(source)[0]
    if roots and hit == os.path.realpath(roots[0]):
        return f"it would overwrite {what}; give another output path"
    return f"it would overwrite {hit!r}, which {what} reads (a sublayer, reference, payload or asset of it); " \
           "give another output path"


def refuse_overwrite(output, given, sources) -> None:
    """ValueError when writing ``output`` (the path as written, ``given`` as the user gave it) would replace a file
    that one of ``sources`` reads: (what, source) pairs as ``overwrite_problem`` takes them."""
    for what, source in sources:
        problem = overwrite_problem(output, source, what)
        if problem is not None:
            raise ValueError(f"usd={str(given)!r} is invalid: {problem}")
