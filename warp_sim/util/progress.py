"""The progress bar of runs and sweeps: tqdm's widget bar inside Jupyter where ipywidgets is installed, its text
bar everywhere else, and never a warning.

``tqdm(...)`` takes tqdm's arguments and picks the bar when it is called, not at ``import warp_sim``:

* in a Jupyter kernel (JupyterLab, Notebook, VS Code, Colab; not qtconsole, Spyder or a terminal IPython) with
  ipywidgets installed: ``tqdm.notebook.tqdm``, the widget bar (ipywidgets is imported then, on the first bar);
* in a Jupyter kernel without ipywidgets: ``tqdm.std.tqdm``, the text bar, shown although the kernel's stderr is
  not a terminal (``disable=None`` is read as False there, as the widget bar reads it); tqdm.autonotebook would
  print a red ``TqdmWarning: IProgress not found`` here and its text bar would hide itself;
* elsewhere: ``tqdm.std.tqdm`` as it is (``disable=None`` hides the bar when stderr is not a terminal).

Whether ipywidgets is installed is asked of ``importlib.util.find_spec``, which finds it without importing it.
Neither this module nor the choice filters any warning. ``tqdm.auto`` is not used: its asyncio support (asyncio,
then ssl) cost about 0.1 s of every ``import warp_sim``.
"""
from __future__ import annotations

import importlib
import importlib.util
import os
import sys

from tqdm.std import tqdm as text_tqdm

__all__ = ["tqdm", "bar_class", "in_notebook", "widgets_available"]


def in_notebook() -> bool:
    """True inside a Jupyter kernel that shows widgets (tqdm.autonotebook's test): an ipykernel shell other than
    qtconsole's or Spyder's, or JupyterLite."""
    if "ipykernel.zmqshell" in sys.modules:
        if any(name == "QT_API" or name.startswith("SPYDER") for name in os.environ):
            return False
        ipython = sys.modules.get("IPython")
        shell = ipython.get_ipython() if ipython is not None and hasattr(ipython, "get_ipython") else None
        kind = type(shell).__name__.lower()
        return shell is not None and "qt" not in kind and "spyder" not in kind
    return "IPython.utils._process_emscripten" in sys.modules


def widgets_available() -> bool:
    """True where ipywidgets can be imported; it is found on the path, not imported."""
    try:
        return importlib.util.find_spec("ipywidgets") is not None
    except (ImportError, ValueError):   # a broken entry in sys.modules or on the path
        return False


def _widget_bar():
    """tqdm.notebook's bar class, or None where its ipywidgets import fails after all."""
    # ipywidgets is an optional dependency, imported where it is used (tests/test_house.py); tqdm.notebook
    # imports it at its own import, so it is imported here, on the first bar, not at ``import warp_sim``.
    notebook = importlib.import_module("tqdm.notebook")
    return notebook.tqdm if getattr(notebook, "IProgress", None) is not None else None


def bar_class():
    """The tqdm class a bar is made of here and now: tqdm.notebook's in Jupyter with ipywidgets, else tqdm.std's."""
    if in_notebook() and widgets_available():
        widget = _widget_bar()
        if widget is not None:
            return widget
    return text_tqdm


def tqdm(*args, **kwargs):
    """A progress bar (tqdm's arguments): the widget bar in Jupyter with ipywidgets, else the text bar."""
    cls = bar_class()
    if cls is text_tqdm and kwargs.get("disable", False) is None and in_notebook():
        kwargs["disable"] = False    # a kernel's stderr is no terminal: tqdm would hide the bar
    return cls(*args, **kwargs)
