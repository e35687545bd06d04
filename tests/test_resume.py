"""Checkpoints and resume: a run stopped at any moment (SIGKILL, SIGTERM, Ctrl-C, a full disk) goes on from its last
checkpoint to a stage identical in every time sample to an uninterrupted run; a checkpoint of another scene or other
run arguments is refused; a checkpoint is data, never code; a completed run leaves nothing but its output."""
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import stage_samples

import warp_sim as ws
from warp_sim.cli import main as ws_main
from warp_sim.demo import demo_scene
from warp_sim.passes.body_contacts import BodyContacts
from warp_sim.stages import writer as writer_module
from warp_sim.stages.runs import CHECKPOINT, RunFolder, run_folder, strays


def assert_same_samples(resumed, reference):
    a, b = stage_samples(resumed), stage_samples(reference)
    assert a.keys() == b.keys()
    different = [key for key in a if a[key] != b[key]]
    assert not different, f"{len(different)} of {len(a)} samples differ, first {different[0]}"


def leftovers(folder):
    return sorted(p.name for p in pathlib.Path(folder).iterdir() if p.name.startswith("."))


def stop_after_checkpoints(monkeypatch, count, error=KeyboardInterrupt):
    """Make a run raise ``error`` right after its ``count``-th checkpoint (a signal arriving then)."""
    real, seen = writer_module.StageWriter.checkpoint, []

    def checkpoint(self, arrays, values):
        real(self, arrays, values)
        seen.append(self.frames_written)
        if len(seen) == count:
            raise error()
    monkeypatch.setattr(writer_module.StageWriter, "checkpoint", checkpoint)
    return seen


def springs_scene(precision="float64"):
    scene = ws.Scene(precision=precision)
    scene.add_ground(restitution=0.5)
    rng = np.random.default_rng(1)
    ids = scene.add_particles(rng.uniform(0.0, 1.0, (12, 3)) + [0.0, 0.5, 0.0], rng.normal(0.0, 1.0, (12, 3)),
                              radius=0.02)
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=200.0, damping=0.1)
    return scene


def jointed_scene():
    """A driven, limited hinge and a ball-jointed pair, no contacts: the joints pass alone, its impulses warm."""
    scene = ws.Scene(precision="float64")
    arm = scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=1.0, position=(0.25, 1.0, 0.0))
    scene.add_joint("revolute", None, arm, anchor=(0.0, 1.0, 0.0), axis=(0.0, 0.0, 1.0), limits=(-1.0, 0.5),
                    drive=ws.Drive(target=0.4, stiffness=20.0, damping=1.0))
    bob = scene.add_rigid_body(ws.Sphere(0.05), mass=0.5, position=(0.75, 1.0, 0.0))
    scene.add_joint("ball", arm, bob, anchor=(0.5, 1.0, 0.0))
    return scene


@pytest.mark.parametrize("make, integrator, seconds", [
    (jointed_scene, lambda: "rk4", 1.0),            # joints alone: their accumulated impulses carried over
    (demo_scene, lambda: "rk4", 1.0),               # emitters, cloth, strain limits, bodies in contact, wind
    (demo_scene, lambda: "implicit_euler", 0.5),    # the conjugate gradient warm start
    (springs_scene, lambda: ws.RK45(rtol=1e-6, atol=1e-9), 1.0),   # the adaptive step size carried over
])
def test_a_resumed_run_is_identical_to_an_uninterrupted_one(tmp_path, monkeypatch, make, integrator, seconds):
    chunk = 12
    reference = ws.Simulator(make(), integrator=integrator()).run(seconds, 60, 4, usd=tmp_path / "whole.usdc",
                                                                  progress=False, chunk_frames=chunk)
    seen = stop_after_checkpoints(monkeypatch, 2)
    out = tmp_path / "cut.usdc"
    with pytest.raises(KeyboardInterrupt) as stopped:
        ws.Simulator(make(), integrator=integrator()).run(seconds, 60, 4, usd=out, progress=False,
                                                          chunk_frames=chunk)
    assert stopped.value.frames_checkpointed == seen[-1] == 2 * chunk and stopped.value.usd == out
    assert not out.exists() and len(leftovers(tmp_path)) == 1    # the run's folder, with its checkpoint
    monkeypatch.undo()
    sim = ws.Simulator(make(), integrator=integrator())
    assert sim.run(seconds, 60, 4, usd=out, progress=False, chunk_frames=chunk, resume=True) == out
    assert_same_samples(out, reference)
    assert leftovers(tmp_path) == []


def test_the_comparison_sees_a_missing_part_of_the_checkpoint(tmp_path, monkeypatch):
    """The identity above is not luck: resumed without the contact response's warm-start table, the demo's pile
    moves differently (so every persistent part is needed, and is checked)."""
    reference = ws.Simulator(demo_scene()).run(1.0, 60, 4, usd=tmp_path / "whole.usdc", progress=False,
                                               chunk_frames=12)
    stop_after_checkpoints(monkeypatch, 2)
    with pytest.raises(KeyboardInterrupt):
        ws.Simulator(demo_scene()).run(1.0, 60, 4, usd=tmp_path / "cut.usdc", progress=False, chunk_frames=12)
    monkeypatch.undo()
    monkeypatch.setattr(BodyContacts, "persistent", ("_capacity",))
    ws.Simulator(demo_scene()).run(1.0, 60, 4, usd=tmp_path / "cut.usdc", progress=False, chunk_frames=12,
                                   resume=True)
    with pytest.raises(AssertionError, match="samples differ"):
        assert_same_samples(tmp_path / "cut.usdc", reference)


@pytest.mark.parametrize("change, shown", [
    (lambda scene, args: scene.add_particles([[0.0, 3.0, 0.0]]), "another scene"),
    (lambda scene, args: args.update(substeps=5), "another scene, simulator or run arguments"),
])
def test_a_checkpoint_of_another_run_is_refused(tmp_path, monkeypatch, change, shown):
    args = dict(seconds=0.5, fps=60, substeps=4, chunk_frames=6)
    stop_after_checkpoints(monkeypatch, 1)
    with pytest.raises(KeyboardInterrupt):
        ws.Simulator(springs_scene()).run(**args, usd=tmp_path / "out.usdc", progress=False)
    monkeypatch.undo()
    scene = springs_scene()
    change(scene, args)
    sim = ws.Simulator(scene)
    with pytest.raises(ValueError, match=shown):
        sim.run(**args, usd=tmp_path / "out.usdc", progress=False, resume=True)
    assert sim.step_count == 0 and len(leftovers(tmp_path)) == 1   # not used, not removed
    sim.run(**args, usd=tmp_path / "out.usdc", progress=False)      # a fresh run starts over and removes it
    assert leftovers(tmp_path) == []


def test_a_checkpoint_is_data_never_code(tmp_path):
    """A checkpoint planted beside an output with a pickled object in it is never unpickled: the resume finds no
    usable checkpoint and starts at frame 0."""
    out = tmp_path / "out.usdc"
    folder = run_folder(out, 2**22 + 17)          # no such process
    folder.mkdir()
    marker = tmp_path / "pwned"

    class Payload:
        def __reduce__(self):
            return (pathlib.Path.touch, (marker,))
    with open(folder / CHECKPOINT, "wb") as f:
        np.savez(f, state=np.array([Payload()], dtype=object), __meta__=np.frombuffer(b"{}", dtype=np.uint8))
    sim = ws.Simulator(springs_scene())
    sim.run(0.2, usd=out, progress=False, resume=True)
    assert not marker.exists()
    assert sim.step_count == 12 - 1 and leftovers(tmp_path) == []   # from frame 0; one step(1/60) a frame (auto)


def test_resume_without_a_checkpoint_starts_over_and_keep_checkpoint_keeps_it(tmp_path):
    out = tmp_path / "out.usdc"
    sim = ws.Simulator(springs_scene())
    sim.run(0.5, usd=out, progress=False, resume=True, keep_checkpoint=True, chunk_frames=10)
    assert sim.step_count == 30 - 1   # substeps='auto': one step(1/60), split as it needs, a frame
    folders = strays(out)
    assert len(folders) == 1 and RunFolder(folders[0]).load_checkpoint()[1]["frames"] == 30
    with pytest.raises(ValueError, match="resume"):
        ws.Simulator(springs_scene()).run(0.5, resume=True, progress=False)


@pytest.mark.parametrize("landed", [True, False])
def test_a_signal_while_a_checkpoint_is_written_keeps_the_one_in_place(tmp_path, monkeypatch, landed):
    """Ctrl-C inside the checkpoint's write, after the new file is renamed into place (landed) or before: the run
    keeps whichever checkpoint is on disk and says how many frames it holds (the new 20 or the last 10), so a
    resume goes on from it. (A real process hit this: SIGINT right after the file appeared left nothing.)"""
    real, calls = RunFolder.save_checkpoint, []

    def save_checkpoint(self, arrays, meta):
        calls.append(meta["frames"])
        if len(calls) == 2:
            if landed:
                real(self, arrays, meta)
            raise KeyboardInterrupt
        real(self, arrays, meta)
    monkeypatch.setattr(RunFolder, "save_checkpoint", save_checkpoint)
    out = tmp_path / "out.usdc"
    with pytest.raises(KeyboardInterrupt) as stopped:
        ws.Simulator(springs_scene()).run(1.0, 60, usd=out, progress=False, chunk_frames=10)
    assert calls == [10, 20] and stopped.value.frames_checkpointed == (20 if landed else 10)
    folders = strays(out)
    assert len(folders) == 1 and RunFolder(folders[0]).load_checkpoint()[1]["frames"] == (20 if landed else 10)
    monkeypatch.undo()
    reference = ws.Simulator(springs_scene()).run(1.0, 60, usd=tmp_path / "whole.usdc", progress=False,
                                                  chunk_frames=10)
    assert ws.Simulator(springs_scene()).run(1.0, 60, usd=out, progress=False, chunk_frames=10, resume=True) == out
    assert_same_samples(out, reference)


# ---- a real process, killed -------------------------------------------------------------------------------------

DEMO = ["demo", "--seconds", "2", "--chunk-frames", "20", "--no-progress"]


def warp_sim(*args, **popen):
    return subprocess.Popen([sys.executable, "-m", "warp_sim.cli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


def wait_for_checkpoint(out, process):
    deadline = time.monotonic() + 180.0
    while not any((folder / CHECKPOINT).exists() for folder in out.parent.glob(f".{out.name}.run-*")):
        assert process.poll() is None and time.monotonic() < deadline, "the run ended before its first checkpoint"
        time.sleep(0.02)


def error_lines(err):
    return [line for line in err.strip().splitlines() if not line.startswith("Warp CUDA warning")]   # no driver here


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("whole") / "demo.usdc"
    process = warp_sim(*DEMO, "--out", str(out))
    process.communicate(timeout=600)
    assert process.returncode == 0
    return out


@pytest.mark.slow   # three demo processes killed and resumed
@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT])
def test_a_killed_command_resumes_to_the_same_stage(tmp_path, uninterrupted, signum):
    """SIGKILL (nothing runs), SIGTERM (exit 143) or Ctrl-C (130) mid-run, then ``--resume``: the stage is identical
    to an uninterrupted run's and nothing else is left."""
    out = tmp_path / "demo.usdc"
    process = warp_sim(*DEMO, "--out", str(out))
    wait_for_checkpoint(out, process)
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == (-signum if signum == signal.SIGKILL else 128 + signum)
    if signum != signal.SIGKILL:
        lines = error_lines(err)
        assert len(lines) == 1 and "Traceback" not in err, err
        assert lines[0].startswith("warp-sim: interrupted") and "--resume" in lines[0] and "checkpointed" in lines[0]
    assert not out.exists() and len(leftovers(tmp_path)) == 1
    resumed = warp_sim(*DEMO, "--out", str(out), "--resume")
    _, err = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, err
    assert_same_samples(out, uninterrupted)
    assert leftovers(tmp_path) == []


@pytest.fixture
def small_disk(tmp_path):
    """A 64 MB tmpfs (root only; skipped where it cannot be mounted)."""
    mount = tmp_path / "disk"
    mount.mkdir()
    if shutil.which("mount") is None or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs",
                                                        str(mount)], capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    yield mount
    subprocess.run(["umount", "-l", str(mount)], check=False)


@pytest.mark.slow   # a tmpfs filled and freed
def test_a_full_disk_keeps_whole_files_only_and_resumes_once_freed(small_disk, tmp_path):
    """The disk fills mid-run: the command prints one line naming the user's path, exits 1 and leaves only whole
    chunks and a checkpoint (no temporary file); once space is freed, --resume completes the same stage as a run
    on a roomy disk. A disk too full for any checkpoint leaves nothing at all."""
    args = ["demo", "--seconds", "1.5", "--chunk-frames", "15", "--no-progress"]
    roomy = warp_sim(*args, "--out", str(tmp_path / "roomy.usdc"))
    roomy.communicate(timeout=600)
    size = (tmp_path / "roomy.usdc").stat().st_size
    ballast = small_disk / "ballast"
    free = shutil.disk_usage(small_disk).free
    ballast.write_bytes(b"\0" * max(0, free - size // 2))          # room for about half the stage
    out = small_disk / "demo.usdc"
    full = warp_sim(*args, "--out", str(out))
    _, err = full.communicate(timeout=600)
    lines = error_lines(err)
    assert full.returncode == 1 and len(lines) == 1 and "Traceback" not in err, err
    assert str(out) in lines[0] and "No space left" in lines[0] and "--resume" in lines[0], lines[0]
    assert not out.exists()
    (folder,) = small_disk.glob(".demo.usdc.run-*")
    assert not [p for p in folder.iterdir() if p.name.endswith(".tmp")]
    assert RunFolder(folder).load_checkpoint() is not None
    ballast.unlink()
    resumed = warp_sim(*args, "--out", str(out), "--resume")
    _, err = resumed.communicate(timeout=600)
    assert resumed.returncode == 0, err
    assert_same_samples(out, tmp_path / "roomy.usdc")
    assert leftovers(small_disk) == []
    out.unlink()
    ballast.write_bytes(b"\0" * (shutil.disk_usage(small_disk).free - 4096))   # no room for anything
    cramped = warp_sim(*args, "--out", str(out))
    _, err = cramped.communicate(timeout=600)
    lines = error_lines(err)
    assert cramped.returncode == 1 and len(lines) == 1 and "No space left" in lines[0], err
    assert sorted(p.name for p in small_disk.iterdir()) == ["ballast"]
    os.sync()


# ---- a damaged run folder -----------------------------------------------------------------------------------------

def damaged_run(tmp_path, monkeypatch, chunk=10):
    """An uninterrupted run's stage, and the folder of the same run stopped after its second checkpoint (20 frames:
    checkpoint.npz lists chunks 0 and 1, checkpoint-previous.npz chunk 0)."""
    args = dict(seconds=1.0, fps=60, substeps=4, chunk_frames=chunk, progress=False)
    reference = ws.Simulator(springs_scene()).run(**args, usd=tmp_path / "whole.usdc")
    stop_after_checkpoints(monkeypatch, 2)
    out = tmp_path / "out.usdc"
    with pytest.raises(KeyboardInterrupt):
        ws.Simulator(springs_scene()).run(**args, usd=out)
    monkeypatch.undo()
    (folder,) = strays(out)
    return reference, out, folder, args


@pytest.mark.parametrize("damage, named, then, first", [
    (lambda folder: (folder / CHECKPOINT).write_bytes(b"not a zip"), CHECKPOINT,
     "going on from frame 10, the checkpoint before it", 10),
    (lambda folder: (folder / CHECKPOINT).write_bytes((folder / CHECKPOINT).read_bytes()[:300]), CHECKPOINT,
     "going on from frame 10, the checkpoint before it", 10),
    (lambda folder: (folder / "chunk-000001.usdc").write_bytes((folder / "chunk-000001.usdc").read_bytes()[:500]),
     "chunk-000001.usdc", "going on from frame 10, the checkpoint before it", 10),
    (lambda folder: (folder / "chunk-000000.usdc").write_bytes(b""), "chunk-000000.usdc",
     "starting over from frame 0", 0),
])
def test_a_damaged_checkpoint_or_chunk_is_said_once_and_the_run_goes_on_from_before_it(tmp_path, monkeypatch, damage,
                                                                                        named, then, first):
    """A checkpoint that is no zip or is cut short, a chunk cut short or emptied: one warning at the start of the
    resume naming the file, then the run goes on from the checkpoint before it (or frame 0) and its stage is an
    uninterrupted run's. (Before: BadZipFile's traceback; a truncated chunk simulated the whole run, then failed
    at the stitch and advised a resume that failed the same way.)"""
    reference, out, folder, args = damaged_run(tmp_path, monkeypatch)
    damage(folder)
    sim = ws.Simulator(springs_scene())
    resumed_at = []
    real = ws.Simulator._frame_loop

    def frame_loop(self, frames, fps, substeps, arrays, first=0, *rest):
        resumed_at.append(first)
        return real(self, frames, fps, substeps, arrays, first, *rest)
    monkeypatch.setattr(ws.Simulator, "_frame_loop", frame_loop)
    with pytest.warns(UserWarning) as said:
        assert sim.run(**args, usd=out, resume=True) == out
    assert len(said) == 1, [str(w.message) for w in said]
    message = str(said[0].message)
    assert message.startswith(f"resume: {folder / named} cannot be read (") and message.endswith(then), message
    assert resumed_at == [first]
    assert_same_samples(out, reference)
    assert leftovers(tmp_path) == []


def test_a_chunk_damaged_after_the_resume_began_is_dropped_so_no_resume_meets_it_again(tmp_path, monkeypatch):
    """The stitch finds a chunk cut short (after the resume's check): the run fails naming it, the chunk and the
    checkpoints listing it go, and the next resume starts over and completes: no loop."""
    reference, out, folder, args = damaged_run(tmp_path, monkeypatch)
    real = writer_module.StageWriter.close

    def close(self, keep_checkpoint=False):
        chunk = self._run.chunks[0]
        chunk.write_bytes(chunk.read_bytes()[:400])
        return real(self, keep_checkpoint)
    monkeypatch.setattr(writer_module.StageWriter, "close", close)
    with pytest.raises(OSError, match="chunk-000000.usdc cannot be read .*; it was removed") as failed:
        ws.Simulator(springs_scene()).run(**args, usd=out, resume=True)
    assert failed.value.frames_checkpointed == 0 and leftovers(tmp_path) == []
    monkeypatch.undo()
    assert ws.Simulator(springs_scene()).run(**args, usd=out, resume=True) == out
    assert_same_samples(out, reference)


def test_the_command_says_a_damaged_checkpoint_in_one_line_and_completes(tmp_path, monkeypatch, capsys):
    args = ["demo", "--seconds", "0.5", "--chunk-frames", "6", "--no-progress"]
    assert ws_main([*args, "--out", str(tmp_path / "whole.usdc")]) == 0
    stop_after_checkpoints(monkeypatch, 2)
    out = tmp_path / "out.usdc"
    assert ws_main([*args, "--out", str(out)]) == 130
    monkeypatch.undo()
    (folder,) = strays(out)
    (folder / CHECKPOINT).write_bytes(b"PK\x03\x04 damaged")
    capsys.readouterr()
    assert ws_main([*args, "--out", str(out), "--resume"]) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"warp-sim: warning: resume: {folder / CHECKPOINT} cannot be read (BadZipFile: File is not a "
                     "zip file); going on from frame 6, the checkpoint before it"], lines
    assert_same_samples(out, tmp_path / "whole.usdc")
