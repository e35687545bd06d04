"""The install story: the notebooks extra brings what the notebooks import beyond the base install, and the
README names it with the command that opens them."""
import ast
import json
import pathlib
import re
import sys

import pytest

tomllib = pytest.importorskip("tomllib")   # Python 3.11+

ROOT = pathlib.Path(__file__).resolve().parent.parent
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
#: import name -> the distribution that provides it (IPython comes with jupyter's kernel)
PROVIDERS = {"warp": "warp-lang", "pxr": "usd-core", "IPython": "jupyter", "warp_sim": "warp-sim"}


def names(requirements) -> set:
    return {re.split(r"[\[<>=~! ;]", r, maxsplit=1)[0].strip().lower() for r in requirements}


def notebook_imports() -> set:
    """The top-level modules every notebook's code cells import."""
    found = set()
    for path in (ROOT / "notebooks").glob("*.ipynb"):
        for cell in json.loads(path.read_text())["cells"]:
            if cell["cell_type"] != "code":
                continue
            for node in ast.walk(ast.parse("".join(cell["source"]))):
                if isinstance(node, ast.Import):
                    found |= {alias.name.split(".")[0] for alias in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    found.add(node.module.split(".")[0])
    return found


def test_the_notebooks_extra_brings_jupyter_ipywidgets_and_matplotlib_and_whatever_the_notebooks_import():
    extra = names(PROJECT["optional-dependencies"]["notebooks"])
    assert {"jupyter", "ipywidgets", "matplotlib"} <= extra
    base = names(PROJECT["dependencies"]) | {"warp-sim"}
    third_party = {m for m in notebook_imports() if m not in sys.stdlib_module_names}
    missing = {m for m in third_party if PROVIDERS.get(m, m).lower() not in base | extra}
    assert not missing, f"the notebooks import {sorted(missing)}, which neither the base install nor the extra has"


def test_the_readme_names_the_extra_and_the_command_that_opens_the_notebooks():
    readme = (ROOT / "README.md").read_text()
    assert '.venv/bin/pip install -e ".[notebooks]" && .venv/bin/jupyter lab notebooks/' in readme
