"""Ctrl-C and SIGTERM honoured at any moment: from the command's first instant (while its libraries import) to the
final stitch, a stopped run exits 130 (143) with one line and leaves an existing output byte-identical, or, once
the new stage is renamed into place, whole and new: never a corrupt one."""
import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from helpers import stage_samples

import warp_sim as ws
from warp_sim.stages import runs as runs_module
from warp_sim.stages import writer as writer_module

KEPT = b"the stage the user meant to keep"


def particles():
    scene = ws.Scene()
    scene.add_ground(restitution=0.5)
    scene.add_particles(np.random.default_rng(0).uniform(0.0, 1.0, (20, 3)) + [0.0, 1.0, 0.0], radius=0.02)
    return scene


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.slow   # four demo processes, each stopped
@pytest.mark.parametrize("delay", [0.3, 0.6, 0.9, 1.3])
def test_ctrl_c_in_the_first_second_exits_130_and_keeps_the_output(tmp_path, delay):
    """SIGINT 0.3 to 1.3 s after launch (imports of Warp, pxr, trimesh and scipy; Warp's start; the run): exit 130,
    one line, the existing output byte-identical. (Before: swallowed during the imports, the run completed and
    replaced it.)"""
    out = tmp_path / "demo.usdc"
    out.write_bytes(KEPT)
    started = time.monotonic()
    process = subprocess.Popen([sys.executable, "-m", "warp_sim", "demo", "--seconds", "60", "--out", str(out),
                                "--no-progress"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(max(0.0, delay - (time.monotonic() - started)))
    assert process.poll() is None, "the command ended before the signal"
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    lines = err.strip().splitlines()
    assert process.returncode == 130 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("warp-sim: interrupted (Ctrl-C)"), lines[0]
    assert out.read_bytes() == KEPT and not [name for name in leftovers(tmp_path) if name.endswith(".tmp")]


def test_sigterm_while_the_chunks_are_stitched_keeps_the_old_file_and_the_checkpoint(tmp_path, monkeypatch):
    reference = ws.Simulator(particles()).run(1.0, usd=tmp_path / "whole.usdc", progress=False, chunk_frames=20)
    out = tmp_path / "out.usdc"
    out.write_bytes(KEPT)
    real = writer_module.UsdUtils.StitchLayers

    def stitch(*args):
        os.kill(os.getpid(), signal.SIGTERM)   # a scheduler stopping the job as the run finishes
        return real(*args)
    monkeypatch.setattr(writer_module.UsdUtils, "StitchLayers", stitch)
    with pytest.raises(ws.RunInterrupted) as stopped:
        ws.Simulator(particles()).run(1.0, usd=out, progress=False, chunk_frames=20)
    assert stopped.value.exit_code == 143 and stopped.value.frames_checkpointed == 60 and not stopped.value.complete
    assert out.read_bytes() == KEPT and len(leftovers(tmp_path)) == 1   # the run's folder, with its checkpoint
    monkeypatch.undo()
    ws.Simulator(particles()).run(1.0, usd=out, progress=False, chunk_frames=20, resume=True)
    assert stage_samples(out) == stage_samples(reference) and leftovers(tmp_path) == []


def test_sigterm_during_the_rename_finds_the_whole_new_stage(tmp_path, monkeypatch):
    reference = ws.Simulator(particles()).run(1.0, usd=tmp_path / "whole.usdc", progress=False, chunk_frames=20)
    out = tmp_path / "out.usdc"
    out.write_bytes(KEPT)
    real = runs_module.os.replace

    def replace(source, target):
        if str(target) == str(out):
            os.kill(os.getpid(), signal.SIGTERM)   # between the rename and the folder's fsync
        return real(source, target)
    monkeypatch.setattr(runs_module.os, "replace", replace)
    with pytest.raises(ws.RunInterrupted) as stopped:
        ws.Simulator(particles()).run(1.0, usd=out, progress=False, chunk_frames=20)
    monkeypatch.undo()
    assert stopped.value.complete and stopped.value.usd == out
    assert stage_samples(out) == stage_samples(reference) and leftovers(tmp_path) == []


def test_the_command_says_sigterm_in_the_final_stitch_in_one_line_and_exits_143(tmp_path):
    """A real process (before: killed, exit -15, no message): SIGTERM while it stitches; one line saying what is
    checkpointed, exit 143, the old output in place."""
    out = tmp_path / "demo.usdc"
    out.write_bytes(KEPT)
    code = textwrap.dedent(f"""
        import os, signal, sys
        sys.argv[0] = os.path.join(os.path.dirname(sys.executable), "warp-sim")
        from warp_sim.stages import writer
        real = writer.UsdUtils.StitchLayers
        def stitch(*args):
            os.kill(os.getpid(), signal.SIGTERM)
            return real(*args)
        writer.UsdUtils.StitchLayers = stitch
        from warp_sim.cli import main
        sys.exit(main(["demo", "--seconds", "0.5", "--chunk-frames", "10", "--out", {str(out)!r}, "--no-progress"]))
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 143 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0] == ("warp-sim: interrupted by SIGTERM; its first 30 frames are checkpointed: run the same "
                        "command with --resume to go on")
    assert out.read_bytes() == KEPT
