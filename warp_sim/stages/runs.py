"""A run's folder beside its output: the chunks of frames already written and the checkpoint to go on from.

A run writing ``out.usdc`` keeps its work in the hidden folder ``.out.run-<pid>/`` next to it:
``chunk-000000.usdc``, ``chunk-000001.usdc``, ... (each a layer of one chunk's time samples, written once) and
``checkpoint.npz`` (what the simulation needs to go on after the last chunk). Every file is written under a
temporary name, flushed to disk and renamed into place, so a kill or a power cut at any moment leaves only
whole files. The checkpoint is data, never code: numpy arrays plus one JSON document, read with
``allow_pickle=False``, so a file planted beside an output cannot run anything.

A folder whose process is no longer alive (or that an earlier run of this process left) is a stray: a new run to
the same output removes it, and a run asked to resume adopts the one whose checkpoint matches it (renamed to its
own process id).
"""
from __future__ import annotations

import contextlib
import json
import os
import pathlib
import re
import shutil

import numpy as np

CHECKPOINT = "checkpoint.npz"
META = "__meta__"    # the checkpoint's JSON document, stored as bytes among its arrays
FORMAT = 1           # the checkpoint format; a checkpoint of another format is refused


def run_folder(path: pathlib.Path, pid: int) -> pathlib.Path:
    """The hidden run folder of process ``pid`` writing ``path``."""
    return path.with_name(f".{path.name}.run-{pid}")


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists (someone else's live process counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def strays(path: pathlib.Path) -> list[pathlib.Path]:
    """The run folders next to ``path`` left by processes no longer alive, or by an earlier run of this process
    (called before a new run makes its own), oldest first."""
    found = []
    for folder in path.parent.glob(f".{path.name}.run-*"):
        pid = folder.name.rsplit("-", 1)[-1]
        if pid.isdigit() and (int(pid) == os.getpid() or not alive(int(pid))):
            found.append(folder)
    return sorted(found, key=lambda folder: folder.stat().st_mtime)


def remove_strays(path: pathlib.Path, keep: pathlib.Path | None = None) -> list[pathlib.Path]:
    """Remove the run folders of dead processes next to ``path`` (but ``keep``); returns them."""
    removed = [folder for folder in strays(path) if folder != keep]
    for folder in removed:
        shutil.rmtree(folder, ignore_errors=True)
    return removed


def _sync_folder(folder: pathlib.Path) -> None:
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


USD_ERROR = re.compile(r"Error in '[^']*' at line \d+ in file [^\n]*? : '(.*)'")


def export_layer(layer, path: pathlib.Path) -> None:
    """``layer.Export(path)``, or OSError with USD's reason (its first error, e.g. "No space left on device")."""
    try:
        if layer.Export(str(path)):
            return
        reason = "the USD export failed"
    except Exception as error:   # pxr.Tf.ErrorException: the first error is the cause, later ones follow from it
        text = str(error).strip()
        found = USD_ERROR.search(text)
        reason = found.group(1) if found else (text.splitlines() or ["the USD export failed"])[0]
        reason = reason.split("Error occurred writing file: ")[-1]
    raise OSError(reason)


def write_atomically(path: pathlib.Path, write) -> None:
    """``write(temporary_path)``, then flush it to disk and rename it onto ``path``; on any failure the temporary
    file is removed and ``path`` is untouched."""
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        write(temporary)
        with open(temporary, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(temporary, path)
        _sync_folder(path.parent)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


class RunFolder:
    """The folder of one run (see the module docstring).

    folder: its path; chunks: the chunk files written, in frame order
    """

    def __init__(self, folder: pathlib.Path):
        self.folder = folder
        self.chunks: list[pathlib.Path] = []

    def create(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)
        self.folder.mkdir()

    def chunk_path(self, index: int) -> pathlib.Path:
        return self.folder / f"chunk-{index:06d}.usdc"

    def add_chunk(self, layer) -> None:
        """Write ``layer`` (an Sdf.Layer holding the next chunk's time samples) as the next chunk file."""
        path = self.chunk_path(len(self.chunks))
        write_atomically(path, lambda temporary: export_layer(layer, temporary))
        self.chunks.append(path)

    def save_checkpoint(self, arrays: dict[str, np.ndarray], meta: dict) -> None:
        """Write the checkpoint: ``arrays`` and the JSON document ``meta`` (which lists the chunks so far)."""
        document = dict(meta, format=FORMAT, chunks=[chunk.name for chunk in self.chunks])
        payload = dict(arrays, **{META: np.frombuffer(json.dumps(document).encode(), dtype=np.uint8)})

        def dump(temporary):
            with open(temporary, "wb") as f:
                np.savez(f, **payload)
        write_atomically(self.folder / CHECKPOINT, dump)

    def load_checkpoint(self) -> tuple[dict[str, np.ndarray], dict] | None:
        """(arrays, meta) of the folder's checkpoint, or None if it has none that reads whole (with its chunks)."""
        path = self.folder / CHECKPOINT
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {name: data[name] for name in data.files}
            meta = json.loads(arrays.pop(META).tobytes().decode())
        except (OSError, ValueError, KeyError, EOFError):
            return None
        if not isinstance(meta, dict) or not all((self.folder / name).is_file() for name in meta.get("chunks", [])):
            return None
        return arrays, meta

    def adopt(self, folder: pathlib.Path, chunks: list[str]) -> None:
        """Take over another (dead) run's folder as this one, keeping its first chunks (``chunks``)."""
        if folder != self.folder:
            shutil.rmtree(self.folder, ignore_errors=True)
            os.replace(folder, self.folder)
        self.chunks = [self.folder / name for name in chunks]
        listed = {path.name for path in self.chunks} | {CHECKPOINT}
        for leftover in self.folder.iterdir():   # chunks past the checkpoint, temporary files
            if leftover.name not in listed:
                leftover.unlink(missing_ok=True)

    def remove(self) -> None:
        with contextlib.suppress(OSError):
            shutil.rmtree(self.folder)
