"""Execute notebooks without Jupyter and save their outputs into the .ipynb files (nbformat 4).

    python tools/run_notebooks.py                       # every notebooks/*.ipynb
    python tools/run_notebooks.py notebooks/00_tour.ipynb --no-save

Each notebook's code cells run in order in one namespace (as tests/test_notebooks.py does), with the
notebook's folder as the working directory and matplotlib on the Agg backend. Lines starting with %
or ! (IPython magics, shell escapes) are skipped. What a cell shows is stored as Jupyter would:

* stdout and stderr as ``stream`` outputs;
* every matplotlib figure the cell leaves open (or shows with ``plt.show()``) as a ``display_data``
  ``image/png`` (then closed);
* every object passed to ``display(obj)``, a function put into the namespace (and served as
  ``IPython.display.display`` while the notebook runs), as ``display_data``: ``text/html`` from
  ``_repr_html_``, else ``image/png`` from ``_repr_png_``, with ``text/plain`` (its repr) always;
* the value of a cell's last expression as an ``execute_result``, as in Jupyter.

In Jupyter the same notebooks import IPython's ``display``. A cell that raises stops the notebook:
its traceback is printed, the file is left as it was and the exit status is 1. Each code cell's
metadata keeps ``warp_sim.source_sha1``, the hash of the source its outputs came from, so a test can
tell stale outputs (tests/test_notebooks.py).
"""
from __future__ import annotations

import argparse
import ast
import base64
import contextlib
import hashlib
import importlib.util
import io
import json
import linecache
import os
import pathlib
import sys
import time
import traceback
import types

ROOT = pathlib.Path(__file__).resolve().parent.parent
NOTEBOOK_DIR = ROOT / "notebooks"
#: The cell metadata key under which the source hash of the saved outputs is kept.
METADATA_KEY = "warp_sim"


class CellError(Exception):
    """A code cell raised: ``notebook`` (file name), ``index`` (among all cells) and the formatted traceback."""

    def __init__(self, notebook: str, index: int, error: BaseException, text: str):
        self.notebook, self.index, self.error, self.traceback = notebook, index, error, text
        super().__init__(f"{notebook}: cell {index} (a code cell) failed: {type(error).__name__}: {error}\n{text}")


def cell_source(cell: dict) -> str:
    source = cell.get("source", "")
    return "".join(source) if isinstance(source, list) else source


def source_hash(cell: dict) -> str:
    """The SHA-1 of a cell's source, as stored in its metadata when its outputs are saved."""
    return hashlib.sha1(cell_source(cell).encode("utf-8")).hexdigest()


def runnable(source: str) -> str:
    """The source without IPython magics and shell escapes (lines starting with % or !)."""
    lines = [line for line in source.splitlines() if not line.lstrip().startswith(("%", "!"))]
    return "\n".join(lines) + "\n"


def load(path: pathlib.Path) -> dict:
    notebook = json.loads(pathlib.Path(path).read_text(encoding="utf-8"))
    if notebook.get("nbformat") != 4:
        raise ValueError(f"{path.name}: expected nbformat 4, got {notebook.get('nbformat')}")
    return notebook


def _lines(text: str) -> list[str]:
    """Text as nbformat's multi-line list of strings (each line keeps its newline)."""
    return text.splitlines(keepends=True)


def mime_bundle(obj) -> dict:
    """What Jupyter would store for ``display(obj)``: text/html, or image/png, and text/plain."""
    data = {}
    html = getattr(obj, "_repr_html_", None)
    png = getattr(obj, "_repr_png_", None)
    if callable(html) and (text := html()) is not None:
        data["text/html"] = _lines(text)
    elif callable(png) and (raw := png()) is not None:
        data["image/png"] = base64.b64encode(raw).decode("ascii")
    data["text/plain"] = _lines(repr(obj))
    return data


class _Outputs:
    """A cell's outputs in order; consecutive writes to one stream merge into one output."""

    def __init__(self):
        self.items: list[dict] = []

    def stream(self, name: str, text: str) -> None:
        if not text:
            return
        last = self.items[-1] if self.items else None
        if last is not None and last["output_type"] == "stream" and last["name"] == name:
            last["text"] = _lines("".join(last["text"]) + text)
        else:
            self.items.append({"output_type": "stream", "name": name, "text": _lines(text)})

    def display(self, data: dict) -> None:
        self.items.append({"output_type": "display_data", "data": data, "metadata": {}})


class _Stream(io.TextIOBase):
    def __init__(self, outputs: _Outputs, name: str):
        self.outputs, self.name = outputs, name

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        self.outputs.stream(self.name, text)
        return len(text)


def _figures(outputs: _Outputs) -> None:
    """Store every open matplotlib figure as image/png, then close them (as the inline backend does)."""
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is None:
        return
    for number in plt.get_fignums():
        figure = plt.figure(number)
        buffer = io.BytesIO()
        figure.savefig(buffer, format="png", bbox_inches="tight")
        width, height = figure.get_size_inches() * figure.dpi
        outputs.display({"image/png": base64.b64encode(buffer.getvalue()).decode("ascii"),
                         "text/plain": [f"<Figure size {width:g}x{height:g} with {len(figure.axes)} Axes>"]})
    plt.close("all")


def _use_agg() -> None:
    os.environ["MPLBACKEND"] = "Agg"
    if "matplotlib" in sys.modules:
        import matplotlib

        matplotlib.use("Agg")


def execute(path, save: bool = False) -> tuple[dict, float]:
    """Run every code cell of the notebook at ``path``; returns (the notebook with outputs, seconds).

    Raises CellError when a cell raises (the file is then not written). With ``save`` the notebook is
    written back with its outputs, execution counts and source hashes."""
    path = pathlib.Path(path).resolve()
    notebook = load(path)
    _use_agg()
    current: list[_Outputs] = [_Outputs()]

    def display(*objects, **_ignored):
        """Show objects in the notebook's output (their _repr_html_, _repr_png_ or repr)."""
        for obj in objects:
            current[0].display(mime_bundle(obj))

    def show(*_args, **_kwargs):
        """plt.show(): the open figures go to the output here."""
        _figures(current[0])

    original_show = []

    def patch_show():
        plt = sys.modules.get("matplotlib.pyplot")
        if plt is not None and not original_show:
            original_show.append(plt.show)
            plt.show = show

    # Where IPython is installed, the notebooks' "from IPython.display import display" gets ours while they
    # run; where it is not, that import fails and the namespace's display (ours too) stays.
    shimmed, saved_display = importlib.util.find_spec("IPython") is not None, None
    if shimmed:
        import IPython  # noqa: F401

        shim = types.ModuleType("IPython.display")
        shim.display = display
        saved_display = sys.modules.get("IPython.display")
        sys.modules["IPython.display"] = shim
    namespace = {"__name__": "__main__", "__file__": str(path), "display": display}
    try:
        import matplotlib.pyplot  # noqa: F401  (so that plt.show() is ours from the first cell on)
    except ImportError:
        pass
    patch_show()
    cwd = os.getcwd()
    count = 0
    start = time.perf_counter()
    try:
        os.chdir(path.parent)
        for index, cell in enumerate(notebook["cells"]):
            if cell.get("cell_type") != "code":
                continue
            count += 1
            outputs = current[0] = _Outputs()
            source = runnable(cell_source(cell))
            filename = f"{path.name}:cell{index}"
            linecache.cache[filename] = (len(source), None, source.splitlines(keepends=True), filename)
            try:
                tree = ast.parse(source, filename)
                last = None
                if tree.body and isinstance(tree.body[-1], ast.Expr) and not source.rstrip().endswith(";"):
                    last = ast.Expression(tree.body.pop().value)
                with contextlib.redirect_stdout(_Stream(outputs, "stdout")), \
                        contextlib.redirect_stderr(_Stream(outputs, "stderr")):
                    exec(compile(tree, filename, "exec"), namespace)
                    value = eval(compile(last, filename, "eval"), namespace) if last is not None else None
            except Exception as error:
                lines = traceback.format_exception(type(error), error, error.__traceback__)
                # drop this runner's own frames: the notebook's start after the first "exec" frame
                text = "".join(lines[:1] + [line for line in lines[1:] if __file__ not in line])
                raise CellError(path.name, index, error, text) from error
            finally:
                _figures(outputs)
            if value is not None:
                outputs.items.append({"output_type": "execute_result", "execution_count": count,
                                      "data": mime_bundle(value), "metadata": {}})
            cell["outputs"] = outputs.items
            cell["execution_count"] = count
            cell.setdefault("metadata", {})[METADATA_KEY] = {"source_sha1": source_hash(cell)}
    finally:
        os.chdir(cwd)
        if original_show:
            sys.modules["matplotlib.pyplot"].show = original_show[0]
        if shimmed and saved_display is not None:
            sys.modules["IPython.display"] = saved_display
        elif shimmed:
            sys.modules.pop("IPython.display", None)
    seconds = time.perf_counter() - start
    if save:
        path.write_text(json.dumps(notebook, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    return notebook, seconds


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("notebooks", nargs="*", type=pathlib.Path,
                        help="notebooks to run (default: every notebooks/*.ipynb)")
    parser.add_argument("--no-save", action="store_true", help="run only; leave the files as they are")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    try:
        import warp as wp

        wp.config.log_level = wp.LOG_WARNING
    except ImportError:
        pass
    paths = args.notebooks or sorted(NOTEBOOK_DIR.glob("*.ipynb"))
    failed = 0
    for path in paths:
        try:
            notebook, seconds = execute(path, save=not args.no_save)
        except CellError as error:
            print(f"FAILED {error}", file=sys.stderr)
            failed += 1
            continue
        kinds = {}
        for cell in notebook["cells"]:
            for output in cell.get("outputs", []):
                for kind in output.get("data", {}) or [output["output_type"]]:
                    kinds[kind] = kinds.get(kind, 0) + 1
        shown = ", ".join(f"{n} {kind}" for kind, n in sorted(kinds.items()))
        print(f"{path.name}: {seconds:.1f} s{'' if args.no_save else ', saved'} ({shown})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
