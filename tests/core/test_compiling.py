"""core.compiling: the estimate of a cold compile, what counts as cached, and ahead-of-time compiles for CUDA
without a GPU (in a fresh process and a fresh WARP_CACHE_PATH, so the shared cache is untouched)."""
import json
import os
import subprocess
import sys
import textwrap

import pytest

from warp_sim import kernels
from warp_sim.core import compiling


def test_the_estimate_is_the_longest_queue_of_the_longest_first_split():
    seconds = kernels.COMPILE_SECONDS
    alone = compiling.estimate(["detection", "contacts", "particles"], workers=1)
    assert alone == pytest.approx(compiling.HEADER_SECONDS + seconds["detection"] + seconds["contacts"]
                                  + seconds["particles"])
    two = compiling.estimate(["detection", "contacts", "particles"], workers=2)
    assert two == pytest.approx(compiling.HEADER_SECONDS + max(seconds["detection"],
                                                               seconds["contacts"] + seconds["particles"]))
    assert compiling.estimate([], workers=4) == 0.0
    assert compiling.estimate(["particles"], workers=1, cuda=True) == pytest.approx(
        compiling.HEADER_SECONDS + compiling.CUDA_FACTOR * seconds["particles"])


def test_every_kernel_module_has_a_name_and_a_compile_time():
    names = compiling.module_names()
    assert len(names) >= 16 and "detection" in names and "blocks" not in names and "geometry" not in names
    assert set(names) <= set(kernels.COMPILE_SECONDS)


def test_notices_can_be_turned_off(capsys):
    before = compiling._notices[0]   # tests/conftest.py turns them off for the whole session
    try:
        compiling.set_notices(True)
        compiling.notice("one")
        compiling.set_notices(False)
        compiling.notice("two")
    finally:
        compiling.set_notices(before)
    assert capsys.readouterr().err == "one\n"
    with pytest.raises(ValueError, match="enabled"):
        compiling.set_notices("no")


CHILD = textwrap.dedent("""
    import json, pathlib, sys, warnings
    import warp as wp
    wp.config.quiet = True
    from warp_sim.core import compiling
    warnings.simplefilter("ignore")
    before = compiling.pending(["particles", "guards"], "cpu")
    rows = compiling.prepare("float32", arches=[80], names=["particles", "guards"])
    again = compiling.prepare("float32", arches=[80], names=["particles"])
    after = compiling.pending(["particles", "guards"], "cpu")
    cache = pathlib.Path(wp.config.kernel_cache_dir)
    files = sorted(".".join(p.name.split(".")[3:]) for p in cache.rglob("*particles*") if p.is_file())
    try:
        compiling.prepare("float64", names=["particles"])
    except ValueError as error:
        refused = str(error)
    print(json.dumps({"before": before, "rows": rows, "again": again, "after": after, "files": files,
                      "refused": refused}))
""")


def test_prepare_compiles_for_the_cpu_and_for_cuda_without_a_gpu(tmp_path):
    """Two modules for the CPU and sm_80 (PTX and CUBIN, through NVRTC): pending before, cached after, a second
    prepare finds them all cached; the other precision in the same process is refused."""
    done = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, WARP_CACHE_PATH=str(tmp_path)))
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["before"] == ["particles", "guards"] and result["after"] == []
    assert sorted((name, target, what) for name, target, what, _ in result["rows"]) == [
        ("guards", "cpu", "compiled"), ("guards", "sm_80", "compiled ptx, cubin"),
        ("particles", "cpu", "compiled"), ("particles", "sm_80", "compiled ptx, cubin")]
    assert sorted((name, target, what) for name, target, what, _ in result["again"]) == [
        ("particles", "cpu", "cached"), ("particles", "sm_80", "cached")]
    assert {"sm80.ptx", "sm80.cubin"} <= set(result["files"]) and any(f.endswith("o") for f in result["files"])
    assert "already declared" in result["refused"]
