"""A run's folder beside its output: the chunks of frames already written and the checkpoint to go on from.

A run writing ``out.usdc`` keeps its work in the hidden folder ``.out.run-<pid>/`` next to it:
``chunk-000000.usdc``, ``chunk-000001.usdc``, ... (each a layer of one chunk's time samples, written once) and
``checkpoint.npz`` (what the simulation needs to go on after the last chunk; each chunk is written before its
checkpoint), with the one before it kept as ``checkpoint-previous.npz``. Every file is written under a
temporary name, flushed to disk and renamed into place, so a kill or a power cut at any moment leaves only
whole files. The checkpoint is data, never code: numpy arrays plus one JSON document, read with
``allow_pickle=False``, so a file planted beside an output cannot run anything.

A file damaged since (a checkpoint that is no zip, a chunk cut short: ``read_checkpoint``, ``read_chunk``) is
found before a resume uses it (``RunFolder.checkpoints``): the newest checkpoint that reads whole with every
chunk it lists is the one to go on from, the previous one when the last does not read or lists a bad chunk,
else none (the run starts over); a chunk that fails the final stitch is dropped with the checkpoints listing it
(``RunFolder.drop``), so no resume meets it again.

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
from pxr import Sdf

from ..util import interrupts

CHECKPOINT = "checkpoint.npz"
PREVIOUS = "checkpoint-previous.npz"   # the checkpoint before the last, for when the last cannot be read
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


def write_atomically(path: pathlib.Path, write, committed=None) -> None:
    """``write(temporary_path)``, then flush it to disk and rename it onto ``path``; on any failure the temporary
    file is removed and ``path`` is untouched. With ``committed`` (a function), SIGINT and SIGTERM wait from the
    rename until ``committed()`` has run (``util.interrupts.held``): a signal then finds ``path`` holding the old
    file or the whole new one, and the caller's record of which."""
    temporary = path.with_name(f".{path.name}.tmp")
    try:
        write(temporary)
        with open(temporary, "rb+") as f:
            os.fsync(f.fileno())
        with interrupts.held() if committed is not None else contextlib.nullcontext():
            os.replace(temporary, path)
            _sync_folder(path.parent)
            if committed is not None:
                committed()
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def read_checkpoint(path: pathlib.Path) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, meta) of a checkpoint file, or ValueError saying why it cannot be read (missing, not a zip, cut
    short, holding an object array, a document without its fields)."""
    try:
        with open(path, "rb") as file, np.load(file, allow_pickle=False) as data:   # closed however np.load fails
            arrays = {name: data[name] for name in data.files}
        meta = json.loads(arrays.pop(META).tobytes().decode())
    except Exception as error:   # OSError, BadZipFile, zlib.error, EOFError, ValueError (pickled data), KeyError
        raise ValueError(error_reason(error)) from None
    if not isinstance(meta, dict) or not isinstance(meta.get("frames"), int) or not isinstance(meta.get("chunks"),
                                                                                                list):
        raise ValueError("it is not a checkpoint: its document has no frames and chunks")
    return arrays, meta


def read_chunk(path: pathlib.Path):
    """The Sdf.Layer of a chunk file, or OSError saying why it cannot be read (USD's first error: "Sdf crate file
    corrupt, possibly truncated", ...)."""
    try:
        layer = Sdf.Layer.OpenAsAnonymous(str(path))
    except Exception as error:   # pxr.Tf.ErrorException
        raise OSError(error_reason(error)) from None
    if layer is None:
        raise OSError("USD cannot open it")
    return layer


def _unreadable(chunk: pathlib.Path) -> str | None:
    """Why a chunk file cannot be read, or None when it can."""
    try:
        read_chunk(chunk)
    except OSError as error:
        return str(error)
    return None


def error_reason(error: Exception) -> str:
    """An error's reason in one line: USD's own message where it is USD's, else its type and first line."""
    if isinstance(error, FileNotFoundError):
        return "it is missing"
    text = str(error).strip()
    found = USD_ERROR.search(text)
    if found:
        return found.group(1)
    first = (text.splitlines() or [""])[0]
    return f"{type(error).__name__}: {first}" if first else type(error).__name__


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
        """Write the checkpoint: ``arrays`` and the JSON document ``meta`` (which lists the chunks so far); the one
        it replaces becomes the previous checkpoint (PREVIOUS), to go on from should this one not read."""
        document = dict(meta, format=FORMAT, chunks=[chunk.name for chunk in self.chunks])
        payload = dict(arrays, **{META: np.frombuffer(json.dumps(document).encode(), dtype=np.uint8)})

        def dump(temporary):
            with open(temporary, "wb") as f:
                np.savez(f, **payload)
        if (self.folder / CHECKPOINT).exists():   # a kill between the two renames leaves the previous one
            os.replace(self.folder / CHECKPOINT, self.folder / PREVIOUS)
        write_atomically(self.folder / CHECKPOINT, dump)

    def checkpoints(self) -> tuple[tuple[dict[str, np.ndarray], dict, str] | None, list[tuple[pathlib.Path, str]]]:
        """(arrays, meta, file name) of the newest checkpoint that reads whole with every chunk it lists (None if
        none does), and the files found damaged on the way: (path, reason) for a checkpoint or a chunk that cannot
        be read."""
        damaged = []
        for name in (CHECKPOINT, PREVIOUS):
            path = self.folder / name
            if not path.exists():
                continue
            try:
                arrays, meta = read_checkpoint(path)
            except ValueError as error:
                damaged.append((path, str(error)))
                continue
            bad = self._first_bad_chunk(meta["chunks"])
            if bad is None:
                return (arrays, meta, name), damaged
            if bad not in damaged:
                damaged.append(bad)
        return None, damaged

    def _first_bad_chunk(self, names: list[str]) -> tuple[pathlib.Path, str] | None:
        for name in names:
            why = _unreadable(self.folder / name)
            if why is not None:
                return self.folder / name, why
        return None

    def load_checkpoint(self) -> tuple[dict[str, np.ndarray], dict] | None:
        """(arrays, meta) of the folder's newest checkpoint that reads whole (with its chunks), or None."""
        found = self.checkpoints()[0]
        return None if found is None else found[:2]

    def adopt(self, folder: pathlib.Path, chunks: list[str], checkpoint: str = CHECKPOINT) -> None:
        """Take over another (dead) run's folder as this one, keeping its first chunks (``chunks``) and the
        checkpoint ``checkpoint`` (a file name) as its own; what is past them goes."""
        if folder != self.folder:
            shutil.rmtree(self.folder, ignore_errors=True)
            os.replace(folder, self.folder)
        if checkpoint != CHECKPOINT:   # the previous checkpoint: the last one did not read, or lists a bad chunk
            os.replace(self.folder / checkpoint, self.folder / CHECKPOINT)
        self.chunks = [self.folder / name for name in chunks]
        listed = {path.name for path in self.chunks} | {CHECKPOINT, PREVIOUS}
        for leftover in self.folder.iterdir():   # chunks past the checkpoint, temporary files
            if leftover.name not in listed:
                leftover.unlink(missing_ok=True)

    def drop(self, chunk: pathlib.Path) -> None:
        """Remove a chunk that cannot be read, the chunks after it and the checkpoints that list it, so that a
        resume goes on from before it (or starts over), never from it again."""
        names = [path.name for path in self.chunks]
        gone = set(names[names.index(chunk.name):]) if chunk.name in names else {chunk.name}
        for name in (CHECKPOINT, PREVIOUS):
            try:
                listed = set(read_checkpoint(self.folder / name)[1]["chunks"])
            except ValueError:
                listed = gone
            if listed & gone:
                (self.folder / name).unlink(missing_ok=True)
        for name in gone:
            (self.folder / name).unlink(missing_ok=True)
        self.chunks = [path for path in self.chunks if path.name not in gone]

    def remove(self) -> None:
        with contextlib.suppress(OSError):
            shutil.rmtree(self.folder)
