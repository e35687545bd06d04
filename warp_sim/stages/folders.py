"""Output folders checked before anything runs: made if missing, refused if a file or not writable.

A sweep (``ws.sweep(out=...)``, ``warp-sim sweep --out``) or a study (``warp-sim study ... --out``) writes its
results into a folder only at the end of minutes of work; a folder that cannot take them must be said at once.
The test is the one that counts: a file made (and removed) in the folder, so a read-only mount, ``/proc`` or a
folder of another user are found whatever the permission bits say (root passes ``os.access`` everywhere).
"""
from __future__ import annotations

import os
import pathlib
import tempfile

__all__ = ["folder_problem"]


def folder_problem(path) -> str | None:
    """Why ``path`` cannot be an output folder, or None when it can (it is made, with its parents, if missing)."""
    folder = pathlib.Path(path)
    if folder.exists() and not folder.is_dir():
        return "it is an existing file; expected a folder"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        return f"the folder cannot be made ({error.strerror or error})"
    try:
        descriptor, probe = tempfile.mkstemp(prefix=".warp-sim-probe-", dir=folder)
    except OSError as error:
        return f"the folder is not writable ({error.strerror or error})"
    os.close(descriptor)
    os.unlink(probe)
    return None
