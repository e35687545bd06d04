"""Execute every notebooks/*.ipynb without Jupyter, and check the outputs saved in the files.

Each notebook's code cells run in order in one namespace, on the CPU with matplotlib's Agg backend,
through tools/run_notebooks.py (which also injects ``display()``); its code cells end with asserts
on the physics, so running them is the test. IPython magics and shell escapes (lines starting with
% or !) are skipped.

The saved files are checked as they are (not re-run): every notebook shows at least one picture
(image/png: a plot) and one preview (text/html: a warp_sim.preview flipbook), and every code cell's
outputs come from its current source. After editing a notebook, run ``python tools/run_notebooks.py``.
"""

import json
import pathlib

import pytest
import warp as wp
from helpers import load_tool

pytestmark = pytest.mark.slow   # every notebook executed: about 15 s

ROOT = pathlib.Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


runner = load_tool("run_notebooks")


@pytest.fixture
def quiet_warp():
    """Warp's module-load messages off while a notebook runs (Warp 1.19: ``config.log_level``)."""
    saved = wp.config.log_level
    wp.config.log_level = wp.LOG_WARNING
    yield
    wp.config.log_level = saved


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 6, [p.name for p in NOTEBOOKS]


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_executes(notebook, quiet_warp):
    try:
        executed, seconds = runner.execute(notebook, save=False)
    except runner.CellError as error:
        pytest.fail(str(error), pytrace=False)
    ran = sum(1 for cell in executed["cells"] if cell.get("cell_type") == "code")
    assert ran > 0, f"{notebook.name} has no code cells"
    print(f"{notebook.name}: {seconds:.1f} s")


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_saved_outputs_show_a_plot_and_a_preview(notebook):
    saved = json.loads(notebook.read_text(encoding="utf-8"))
    assert saved.get("nbformat") == 4
    stale = []
    kinds = {}
    for index, cell in enumerate(saved["cells"]):
        if cell.get("cell_type") != "code":
            continue
        recorded = cell.get("metadata", {}).get(runner.METADATA_KEY, {}).get("source_sha1")
        if cell.get("execution_count") is None or recorded != runner.source_hash(cell):
            stale.append(index)
        for output in cell.get("outputs", []):
            assert output.get("output_type") != "error", f"{notebook.name}: cell {index} saved an error"
            for kind, value in output.get("data", {}).items():
                kinds.setdefault(kind, []).append("".join(value) if isinstance(value, list) else value)
    assert not stale, (f"{notebook.name}: the saved outputs of code cells {stale} are not from their current "
                       f"source; run python tools/run_notebooks.py")
    assert kinds.get("image/png"), f"{notebook.name}: no image/png output saved"
    previews = [html for html in kinds.get("text/html", []) if "warp-sim-flipbook" in html
                and "data:image/png;base64," in html]
    assert previews, f"{notebook.name}: no warp_sim.preview flipbook (text/html) saved"
