"""stages.inputs: the output never overwrites an input. The files a stage reads (its root, sublayers recursively,
references, payloads, variants' arcs, a reference not written yet), matched by real path; refused from Python
(usd=/over=, a ValueError before anything is made or simulated) and from the command line (one line, exit 2)."""
import os
import shutil
from pathlib import Path

import pytest
from pxr import Usd

import warp_sim as ws
from warp_sim.cli import main
from warp_sim.stages.inputs import files_read, overwritten

EXAMPLE = Path(ws.examples.path("tabletop_cm.usda"))


def write(path: Path, text: str) -> Path:
    path.write_text("#usda 1.0\n" + text)
    return path


@pytest.fixture
def stack(tmp_path):
    """scene.usda: the example, sublayered by top.usda through mid.usda, which also references and pays load."""
    shutil.copy(EXAMPLE, tmp_path / "scene.usda")
    write(tmp_path / "ref.usda", '(\n    defaultPrim = "R"\n)\ndef Xform "R" {}\n')
    write(tmp_path / "pay.usda", '(\n    defaultPrim = "P"\n)\ndef Xform "P" {}\n')
    write(tmp_path / "variant.usda", '(\n    defaultPrim = "V"\n)\ndef Xform "V" {}\n')
    write(tmp_path / "mid.usda", '(\n    subLayers = [@./scene.usda@]\n)\n')
    write(tmp_path / "top.usda", top_layer_text())
    return tmp_path


def top_layer_text() -> str:
    return ('(\n    subLayers = [@mid.usda@]\n)\n'
            'def Xform "A" (\n    references = @ref.usda@\n) {}\n'
            'def Xform "B" (\n    payload = @pay.usda@\n) {}\n'
            'def Xform "C" (\n    references = @later.usda@\n) {}\n'
            'def Xform "D" (\n    variants = {\n        string look = "a"\n    }\n    prepend variantSets = "look"\n)'
            ' {\n    variantSet "look" = {\n        "a" (\n            references = @variant.usda@\n        ) {}\n'
            '    }\n}\n')


def test_every_file_of_the_layer_stack_is_found(stack):
    found = files_read(stack / "top.usda")
    names = {os.path.basename(path) for path in found}
    assert names == {"top.usda", "mid.usda", "scene.usda", "ref.usda", "pay.usda", "variant.usda", "later.usda"}
    assert found[0] == os.path.realpath(stack / "top.usda")
    assert set(files_read(Usd.Stage.Open(str(stack / "top.usda")))) == set(found)   # a stage: the same files


def test_other_spellings_of_a_path_are_the_same_file(stack, monkeypatch):
    monkeypatch.chdir(stack)
    os.symlink("scene.usda", stack / "link.usda")
    os.link(stack / "ref.usda", stack / "hard.usda")
    for output in ("scene.usda", "./scene.usda", str(stack / "scene.usda"), "link.usda", "../" + stack.name +
                   "/scene.usda"):
        assert overwritten(output, "scene.usda") == os.path.realpath(stack / "scene.usda"), output
    assert overwritten("hard.usda", "top.usda") == os.path.realpath(stack / "ref.usda")   # a hard link
    assert overwritten("scene.usdc", "scene.usda") is None and overwritten("out.usda", "top.usda") is None


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    folder = tmp_path_factory.mktemp("input")
    shutil.copy(EXAMPLE, folder / "scene.usda")
    write(folder / "top.usda", '(\n    subLayers = [@./scene.usda@]\n)\n')
    return ws.Simulator(ws.Scene.from_usd(folder / "top.usda")), folder


@pytest.mark.parametrize("usd, over, shown", [
    ("top.usda", "top.usda", "it would overwrite the input stage over='top.usda'"),
    ("./top.usda", "top.usda", "the input stage over='top.usda'"),
    ("{folder}/top.usda", "top.usda", "the input stage over='top.usda'"),
    ("link.usda", "top.usda", "the input stage over='top.usda'"),
    ("scene.usda", "top.usda", "scene.usda', which the input stage over='top.usda' reads (a sublayer"),
    ("top.usda", None, "the stage the scene was read from"),
    ("scene.usda", None, "which the stage the scene was read from"),
])
@pytest.mark.parametrize("flatten", [False, True])
def test_run_refuses_an_output_that_is_an_input_before_anything(sim, monkeypatch, usd, over, shown, flatten):
    simulator, folder = sim
    monkeypatch.chdir(folder)
    if not (folder / "link.usda").exists():
        os.symlink("top.usda", folder / "link.usda")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(ValueError, match="usd=.* is invalid: ") as refused:
        simulator.run(0.2, usd=usd.format(folder=folder), over=over, flatten=flatten and over is not None,
                      progress=False)
    assert shown in str(refused.value) and "give another output path" in str(refused.value)
    assert simulator.step_count == 0                                       # nothing simulated,
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before   # nothing made, nothing changed


def test_run_over_a_usd_stage_object_refuses_its_layers(sim, monkeypatch):
    simulator, folder = sim
    with pytest.raises(ValueError, match="scene.usda', which the input stage over="):
        simulator.run(0.2, usd=folder / "scene.usda", over=Usd.Stage.Open(str(folder / "top.usda")), progress=False)


@pytest.mark.parametrize("out, shown", [
    ("scene.usda", "--out scene.usda is invalid: it would overwrite the input scene.usda; give another output path"),
    ("./scene.usda", "--out ./scene.usda is invalid: it would overwrite the input scene.usda"),
    ("link.usda", "--out link.usda is invalid: it would overwrite the input scene.usda"),
])
@pytest.mark.parametrize("flatten", [[], ["--flatten"]])
def test_the_command_line_refuses_in_one_line(tmp_path, monkeypatch, capsys, out, shown, flatten):
    monkeypatch.chdir(tmp_path)
    shutil.copy(EXAMPLE, "scene.usda")
    os.symlink("scene.usda", "link.usda")
    before = Path("scene.usda").read_bytes()
    assert main(["run", "scene.usda", "--out", out, "--seconds", "0.2", *flatten]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"warp-sim: error: {shown}"), lines
    assert Path("scene.usda").read_bytes() == before and sorted(os.listdir()) == ["link.usda", "scene.usda"]


def test_the_command_line_refuses_a_sublayer_of_the_input(stack, monkeypatch, capsys):
    monkeypatch.chdir(stack)
    before = Path("scene.usda").read_bytes()
    assert main(["run", "top.usda", "--out", "scene.usda", "--seconds", "0.2"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == (f"warp-sim: error: --out scene.usda is invalid: it would overwrite "
                    f"{os.path.realpath('scene.usda')!r}, which the input top.usda reads (a sublayer, reference, "
                    "payload or asset of it); give another output path")
    assert Path("scene.usda").read_bytes() == before
