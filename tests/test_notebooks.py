"""Execute every notebooks/*.ipynb without Jupyter: its code cells, in order, in one namespace.

Each notebook's code cells end with asserts on the physics, so running them is the test.
IPython magics and shell escapes (lines starting with % or !) are skipped.
"""

import json
import linecache
import pathlib
import traceback

import pytest
import warp as wp

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))


def code_cells(path: pathlib.Path):
    """(index among all cells, source) of each code cell of a notebook (nbformat 4 JSON)."""
    notebook = json.loads(path.read_text(encoding="utf-8"))
    assert notebook.get("nbformat") == 4, f"{path.name}: expected nbformat 4, got {notebook.get('nbformat')}"
    for index, cell in enumerate(notebook["cells"]):
        if cell.get("cell_type") != "code":
            continue
        source = cell.get("source", "")
        text = "".join(source) if isinstance(source, list) else source
        lines = [line for line in text.splitlines() if not line.lstrip().startswith(("%", "!"))]
        yield index, "\n".join(lines) + "\n"


@pytest.fixture
def quiet_warp():
    """Warp's module-load messages off while a notebook runs (Warp 1.19: ``config.log_level``)."""
    saved = wp.config.log_level
    wp.config.log_level = wp.LOG_WARNING
    yield
    wp.config.log_level = saved


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_executes(notebook, quiet_warp):
    namespace = {"__name__": "__main__", "__file__": str(notebook)}
    ran = 0
    for index, source in code_cells(notebook):
        filename = f"{notebook.name}:cell{index}"
        # register the source so that tracebacks show the notebook's lines
        linecache.cache[filename] = (len(source), None, source.splitlines(keepends=True), filename)
        try:
            exec(compile(source, filename, "exec"), namespace)
        except Exception as exc:
            pytest.fail(f"{notebook.name}: cell {index} (a code cell) failed: {type(exc).__name__}: {exc}\n"
                        f"{traceback.format_exc()}", pytrace=False)
        ran += 1
    assert ran > 0, f"{notebook.name} has no code cells"
