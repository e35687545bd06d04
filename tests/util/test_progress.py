"""warp_sim.util.progress: the widget bar only in a Jupyter kernel with ipywidgets, the text bar (shown, and
without a TqdmWarning) in a kernel without it, tqdm's own text bar elsewhere; ipywidgets never imported by
``import warp_sim``. A kernel is simulated by the modules tqdm.autonotebook looks for (ipykernel.zmqshell, and
IPython.get_ipython() returning a ZMQInteractiveShell); ipywidgets' absence by patching find_spec."""
import importlib
import importlib.util
import io
import subprocess
import sys
import types
import warnings

import pytest
import tqdm.std

from warp_sim.util import progress


class ZMQInteractiveShell:   # the class name ipykernel's shell has
    pass


@pytest.fixture
def kernel(monkeypatch):
    """As inside a Jupyter kernel: ipykernel.zmqshell imported, get_ipython() an ipykernel shell."""
    monkeypatch.setitem(sys.modules, "ipykernel.zmqshell", types.ModuleType("ipykernel.zmqshell"))
    if importlib.util.find_spec("IPython") is not None:        # installed: its get_ipython() says a kernel
        monkeypatch.setattr(importlib.import_module("IPython"), "get_ipython", ZMQInteractiveShell)
    else:
        fake = types.ModuleType("IPython")
        fake.get_ipython = ZMQInteractiveShell
        monkeypatch.setitem(sys.modules, "IPython", fake)
    for name in ("QT_API", "SPYDER_ARGS"):
        monkeypatch.delenv(name, raising=False)
    assert progress.in_notebook()


@pytest.fixture
def no_ipywidgets(monkeypatch):
    """ipywidgets not installed, as find_spec says it: every other module is found as before."""
    real = importlib.util.find_spec

    def find_spec(name, package=None):
        return None if name == "ipywidgets" or name.startswith("ipywidgets.") else real(name, package)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    assert not progress.widgets_available()


def bar_output(**kwargs) -> tuple[str, list]:
    """(what a 3-step bar printed, the warnings raised while it was made and run)."""
    out = io.StringIO()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with progress.tqdm(total=3, unit="frame", file=out, **kwargs) as bar:
            for _ in range(3):
                bar.update(1)
    return out.getvalue(), caught


def test_kernel_without_ipywidgets_shows_the_text_bar_without_a_warning(kernel, no_ipywidgets):
    assert progress.bar_class() is tqdm.std.tqdm
    text, caught = bar_output(disable=None)   # what Simulator.run passes with progress=True
    assert "3/3" in text and "frame" in text, text        # shown: a kernel's stderr is no terminal
    assert not [w for w in caught if issubclass(w.category, tqdm.std.TqdmWarning)], [str(w.message) for w in caught]
    assert not caught, [str(w.message) for w in caught]


def test_kernel_with_ipywidgets_gets_the_widget_bar(kernel, monkeypatch):
    class WidgetBar(tqdm.std.tqdm):
        pass

    monkeypatch.setattr(importlib.util, "find_spec", lambda name, package=None: object())
    monkeypatch.setattr(progress, "_widget_bar", lambda: WidgetBar)
    assert progress.widgets_available() and progress.bar_class() is WidgetBar
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bar = progress.tqdm(total=2, file=io.StringIO())
    assert type(bar) is WidgetBar
    bar.close()


def test_kernel_with_broken_ipywidgets_falls_back_to_the_text_bar(kernel, monkeypatch):
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, package=None: object())
    monkeypatch.setattr(progress, "_widget_bar", lambda: None)   # tqdm.notebook's IProgress is None
    assert progress.bar_class() is tqdm.std.tqdm


def test_real_widget_bar_where_ipywidgets_is_installed(kernel):
    pytest.importorskip("ipywidgets")
    import tqdm.notebook

    assert progress.bar_class() is tqdm.notebook.tqdm


def test_outside_jupyter_the_text_bar_is_tqdms_own(monkeypatch):
    monkeypatch.delitem(sys.modules, "ipykernel.zmqshell", raising=False)
    monkeypatch.delitem(sys.modules, "IPython.utils._process_emscripten", raising=False)
    assert not progress.in_notebook() and progress.bar_class() is tqdm.std.tqdm
    text, caught = bar_output(disable=False)
    assert "3/3" in text and not caught
    text, _ = bar_output(disable=None)     # not a terminal: hidden, as tqdm does
    assert text == ""


def test_qtconsole_is_not_a_notebook(kernel, monkeypatch):
    monkeypatch.setenv("QT_API", "pyqt5")
    assert not progress.in_notebook()


def test_import_warp_sim_imports_no_widgets_and_no_autonotebook():
    code = ("import sys, warp_sim; print(sorted(m for m in ('ipywidgets', 'tqdm.notebook', 'tqdm.autonotebook', "
            "'tqdm.auto', 'asyncio') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]", done.stdout
    assert "Warning" not in done.stderr, done.stderr[-2000:]
