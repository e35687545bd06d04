"""Every python block of README starts with its imports and runs as written, each in a fresh interpreter in a
an empty temporary folder (example stages come from the package: ws.examples), printing nothing of Warp's (no
banner, no module-load lines); the kernels block checks its kernels against numpy with its own asserts."""
import pathlib
import re
import subprocess
import sys

import pytest

README = pathlib.Path(__file__).resolve().parent.parent / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


SELF_CONTAINED = [block for block in python_blocks() if block.lstrip().startswith(("import ", "from "))]


def test_every_block_is_self_contained():
    assert len(SELF_CONTAINED) == len(python_blocks()) >= 6
    assert any("spring_forces" in block for block in SELF_CONTAINED)


@pytest.mark.parametrize("block", SELF_CONTAINED, ids=lambda b: b.splitlines()[-1][:40])
def test_readme_block_runs(block, tmp_path):
    script = tmp_path / "block.py"
    script.write_text(block)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Module " not in done.stdout and "Warp " not in done.stdout, done.stdout[:500]
