"""ws.examples: the example stages shipped inside the package. Every one loads and moves; a bad name is a
ValueError listing the names; copy() writes a stage and the files it reads where it opens as it did, and never
overwrites a file that differs; the wheel's package data holds every example file."""
import ast
import fnmatch
import pathlib
import re

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import warp_sim as ws
from warp_sim import examples

ROOT = pathlib.Path(__file__).resolve().parent.parent


def test_names_and_paths():
    names = ws.examples.names()
    assert "tabletop_cm.usda" in names and names == sorted(names)
    for name in names:
        path = pathlib.Path(ws.examples.path(name))
        assert path.is_absolute() and path.is_file() and path.name == name
        assert path.parent == pathlib.Path(ws.__file__).resolve().parent / "examples"   # inside the package


@pytest.mark.parametrize("bad", ["nope.usda", "tabletop_cm", "examples/tabletop_cm.usda", None])
def test_a_bad_name_lists_the_names(bad):
    with pytest.raises(ValueError) as caught:
        ws.examples.path(bad)
    text = str(caught.value)
    assert text.startswith(f"name={bad!r} is invalid: expected one of ") and "tabletop_cm.usda" in text, text


@pytest.mark.parametrize("name", examples.names())
def test_every_example_loads_and_moves(name):
    """Three frames at 60 fps (the last at t = 2/60 s): every body and particle stays finite, none rises, and the
    one that falls furthest (a free one: each example drops something) has fallen g t^2 / 2 within 1 %."""
    scene = ws.Scene.from_usd(ws.examples.path(name))
    assert scene.usd_paths, name
    sim = ws.Simulator(scene, device="cpu")
    down = np.asarray(scene.gravity) / np.linalg.norm(scene.gravity)
    fields = [field for field in ("body_x", "particle_x") if hasattr(sim.state, field)]
    before = [getattr(sim.state, field).numpy().copy() for field in fields]
    sim.run(seconds=3 / 60, fps=60, progress=False)
    after = [getattr(sim.state, field).numpy() for field in fields]
    assert all(np.isfinite(x).all() for x in after)
    drops = np.concatenate([(x - x0) @ down for x, x0 in zip(after, before)])
    assert drops.min() >= -1e-6
    assert drops.max() == pytest.approx(0.5 * np.linalg.norm(scene.gravity) * (2 / 60) ** 2, rel=0.01)


def stage_with_files(folder: pathlib.Path) -> None:
    """A stage in ``folder`` that sublayers parts/base.usda, which references parts/crate.usda."""
    (folder / "parts").mkdir(parents=True)
    crate = Usd.Stage.CreateNew(str(folder / "parts" / "crate.usda"))
    crate.SetDefaultPrim(UsdGeom.Cube.Define(crate, "/Crate").GetPrim())
    crate.Save()
    base = Usd.Stage.CreateNew(str(folder / "parts" / "base.usda"))
    base.DefinePrim("/World/crate").GetReferences().AddReference("./crate.usda")
    base.Save()
    top = Usd.Stage.CreateNew(str(folder / "scene.usda"))
    top.GetRootLayer().subLayerPaths.append("./parts/base.usda")
    top.Save()


def test_copy_takes_the_files_a_stage_reads(tmp_path, monkeypatch):
    monkeypatch.setattr(examples, "FOLDER", tmp_path / "shipped")
    stage_with_files(tmp_path / "shipped")
    assert examples.names() == ["scene.usda"]
    assert examples.files("scene.usda") == ["scene.usda", "parts/base.usda", "parts/crate.usda"]
    out = examples.copy("scene.usda", tmp_path / "mine" / "new")          # made, with its parents
    assert out == str(tmp_path / "mine" / "new" / "scene.usda")
    copied = Usd.Stage.Open(out)
    assert copied.GetPrimAtPath("/World/crate").GetTypeName() == "Cube"   # composed from the copies
    used = [layer.realPath for layer in copied.GetUsedLayers() if not layer.anonymous]
    assert len(used) == 3 and all(path.startswith(str(tmp_path / "mine")) for path in used), used
    assert examples.copy("scene.usda", tmp_path / "mine" / "new") == out  # the same files again: fine


def test_copy_never_overwrites_a_different_file(tmp_path):
    first = pathlib.Path(ws.examples.copy("tabletop_cm.usda", tmp_path))
    first.write_text(first.read_text() + "# the user's edit\n")
    with pytest.raises(ValueError) as caught:
        ws.examples.copy("tabletop_cm.usda", tmp_path)
    text = str(caught.value)
    assert text.startswith(f"folder={str(tmp_path)!r} is invalid: {first} exists and differs") and "another" in text
    assert first.read_text().endswith("# the user's edit\n")
    with pytest.raises(ValueError, match=r"folder=.* is invalid: it is an existing file; expected a folder"):
        ws.examples.copy("tabletop_cm.usda", first)


def test_the_wheel_ships_every_example_file():
    """pyproject's package data for warp_sim.examples matches every file of the folder but the Python ones."""
    table = (ROOT / "pyproject.toml").read_text().split("[tool.setuptools.package-data]", 1)[1].split("\n[", 1)[0]
    shipped = ast.literal_eval(re.search(r'^"warp_sim\.examples" = (\[.*\])$', table, flags=re.M).group(1))
    data = [item.name for item in examples.FOLDER.iterdir() if item.is_file() and item.suffix not in (".py", ".pyc")]
    assert data and all(any(fnmatch.fnmatch(name, pattern) for pattern in shipped) for name in data), data
    assert not list(ROOT.glob("examples/*.usd*"))   # one copy only: the package's
