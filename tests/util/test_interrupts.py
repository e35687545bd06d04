"""util.interrupts: a Ctrl-C while warp_sim imports is recorded (no library can swallow it) and raised at the end of
the import, or, in the command, said by its main; signals wait while a finished stage is renamed into place; which
process is the command."""
import signal
import subprocess
import sys
import textwrap

import pytest

from warp_sim.util import interrupts

#: a Ctrl-C sent from inside the import of ``TARGET``, which the library importing it catches when not deferred
#: (pxr's script-module loader prints the traceback and goes on, breaking pxr; trimesh keeps an ExceptionWrapper)
TRIP = textwrap.dedent("""
    import os, signal, sys

    class Trip:
        done = False

        def find_spec(self, name, path=None, target=None):
            if name == TARGET and not self.done:
                self.done = True
                os.kill(os.getpid(), signal.SIGINT)
            return None

    trip = Trip()
    sys.meta_path.insert(0, trip)
""")


def python(code: str, timeout=300):
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("target", ["pxr.Vt", "networkx"])
def test_a_ctrl_c_inside_a_library_that_swallows_it_raises_at_the_end_of_import_warp_sim(target):
    code = f"TARGET = {target!r}\n" + TRIP + textwrap.dedent("""
        try:
            import warp_sim
        except KeyboardInterrupt:
            sys.exit(3 if trip.done and signal.getsignal(signal.SIGINT) is signal.default_int_handler else 4)
        print("imported: the Ctrl-C was lost" if trip.done else "never imported")
    """)
    done = python(code)
    assert done.returncode == 3, done.stdout + done.stderr
    assert "Error loading lib" not in done.stderr and "postprocessing module" not in done.stderr


def test_the_command_says_a_ctrl_c_from_its_imports_and_touches_nothing(tmp_path):
    """As the console script: the Ctrl-C inside pxr's loader is said by main, exit 130, the output untouched."""
    out = tmp_path / "kept.usdc"
    out.write_bytes(b"the user's stage")
    code = "TARGET = 'pxr.Vt'\n" + TRIP + textwrap.dedent(f"""
        sys.argv[0] = os.path.join(os.path.dirname(sys.executable), "warp-sim")
        from warp_sim.cli import main
        sys.exit(main(["demo", "--seconds", "0.2", "--out", {str(out)!r}, "--no-progress"]))
    """)
    done = python(code)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 130 and lines == ["warp-sim: interrupted (Ctrl-C); nothing was written"], done.stderr
    assert out.read_bytes() == b"the user's stage" and sorted(p.name for p in tmp_path.iterdir()) == ["kept.usdc"]


@pytest.mark.parametrize("argv, orig, command", [
    (["/venv/bin/warp-sim", "demo"], ["/venv/bin/python", "/venv/bin/warp-sim", "demo"], True),
    (["-m", "demo"], ["python", "-m", "warp_sim", "demo"], True),
    (["-m", "demo"], ["python", "-X", "importtime", "-m", "warp_sim.cli", "demo"], True),
    (["-m"], ["python", "-mwarp_sim"], True),
    (["-m"], ["python", "-m", "pytest", "tests"], False),
    (["-c"], ["python", "-c", "import warp_sim", "-m", "warp_sim"], False),
    (["script.py"], ["python", "script.py"], False),
])
def test_which_process_is_the_command(monkeypatch, argv, orig, command):
    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(sys, "orig_argv", orig)
    assert interrupts.is_command() is command


def test_held_signals_wait_for_the_end_of_the_block():
    seen = []
    with pytest.raises(KeyboardInterrupt):
        with interrupts.held():
            signal.raise_signal(signal.SIGINT)
            seen.append("the block went on")
    assert seen == ["the block went on"] and signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_armed_raises_what_was_recorded_then_records_and_raises_each_signal():
    before = signal.getsignal(signal.SIGTERM)
    interrupts.record(signal.SIGTERM)
    with pytest.raises(interrupts.RunInterrupted) as stopped:
        with interrupts.armed():
            pytest.fail("a signal recorded before main must stop it at once")
    assert stopped.value.exit_code == 143 and interrupts.pending() is None
    with pytest.raises(KeyboardInterrupt):
        with interrupts.armed():
            try:
                signal.raise_signal(signal.SIGINT)
            except KeyboardInterrupt:   # as a library swallowing it would: still recorded
                assert interrupts.pending() == signal.SIGINT
            interrupts.raise_pending()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler and signal.getsignal(signal.SIGTERM) == before
    assert interrupts.pending() is None


def test_release_gives_a_library_user_the_ctrl_c_at_the_end_of_the_import(monkeypatch):
    monkeypatch.setattr(sys, "orig_argv", ["python", "script.py"])
    monkeypatch.setattr(interrupts, "_previous", {})
    interrupts.defer()
    assert signal.getsignal(signal.SIGINT) is interrupts.record
    signal.raise_signal(signal.SIGINT)   # recorded, not raised
    with pytest.raises(KeyboardInterrupt):
        interrupts.release()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler and interrupts.pending() is None
