"""benchmarks/compare.py --baseline: a revision checked out in a temporary git worktree (compare.worktree, removed
afterwards), its workers importing that revision's warp_sim, its rows beside the working tree's in the same rounds,
and the table of their ratios. Nothing about times."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import compare  # noqa: E402


def git(*args) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True).stdout


@pytest.fixture(scope="module", autouse=True)
def a_git_checkout():
    if subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet", "HEAD"],
                      capture_output=True).returncode != 0:
        pytest.skip("not a git checkout: no revision to check out")


def test_a_worktree_holds_the_revision_and_is_removed_afterwards():
    head = git("rev-parse", "HEAD").strip()
    with compare.worktree("HEAD") as (root, commit):
        assert commit == head
        assert (root / "warp_sim" / "__init__.py").is_file()
        assert str(root) in git("worktree", "list", "--porcelain")
        assert subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                              text=True).stdout.strip() == head
    assert not root.exists() and not root.parent.exists()
    assert str(root) not in git("worktree", "list", "--porcelain")


def test_a_worktree_is_removed_when_its_run_raises():
    with pytest.raises(RuntimeError, match="inside"):
        with compare.worktree("HEAD") as (root, _):
            raise RuntimeError("inside")
    assert not root.exists() and str(root) not in git("worktree", "list", "--porcelain")


def test_an_unknown_revision_is_refused_before_anything_is_made():
    with pytest.raises(ValueError, match="not a commit"):
        with compare.worktree("no-such-revision-anywhere"):
            pass


def test_a_baseline_worker_imports_the_worktrees_warp_sim_or_fails(tmp_path, monkeypatch):
    monkeypatch.delenv("PYTHONPATH", raising=False)
    assert compare.baseline_command(["python", "w.py"], tmp_path) == ["env", f"PYTHONPATH={tmp_path}", "python", "w.py"]
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    assert compare.baseline_command(["python"], tmp_path)[1] == f"PYTHONPATH={tmp_path}:/elsewhere"
    assert compare.imported_from({"status": "ok", "warp_sim_path": str(tmp_path / "warp_sim")}, tmp_path) == {
        "status": "ok", "warp_sim_path": str(tmp_path / "warp_sim")}
    wrong = compare.imported_from({"status": "ok", "warp_sim_path": str(ROOT / "warp_sim")}, tmp_path)
    assert wrong["status"].startswith("failed: imported warp_sim from")
    assert compare.imported_from({"status": "failed: x"}, tmp_path) == {"status": "failed: x"}


def test_a_quick_cloth_run_against_head_as_the_baseline(tmp_path):
    """The working tree's warp_sim against HEAD's (its kernels the same, so already compiled): both cloth sizes
    checked and timed in turn, the baseline's workers on the worktree's warp_sim, the ratio table printed."""
    out = tmp_path / "compare.json"
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "compare.py"), "--device", "cpu", "--quick",
                           "--workloads", "cloth", "--only", "warp_sim", "--baseline", "HEAD", "--copy-mb", "8",
                           "--out", str(out)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    short = git("rev-parse", "--short=7", "HEAD").strip()
    assert sum(line.startswith(f"| cloth | {n}x{n} | warp_sim @ HEAD ({short}) (guard off) | pass")
               for n in (32, 64) for line in lines) == 2
    header = next(line for line in lines if line.startswith("| workload | size | warp_sim (working tree) steps/s"))
    assert "warp_sim @ HEAD steps/s" in header and "working tree / HEAD" in header
    result = json.loads(out.read_text())
    assert [b["revision"] for b in result["baselines"]] == ["HEAD"]
    rows = [row for row in result["rows"] if row["key"] == "warp_sim@HEAD"]
    assert [row["size"] for row in rows] == [32, 64]
    for row in rows:
        assert row["status"] == "ok" and row["check"]["pass"]
        assert len(row["seconds"]) == 3 and row["paired_ratio"] > 0.0
        path = Path(row["warp_sim_path"])
        assert path.name == "warp_sim" and path.parent != ROOT and "warp_sim-baseline-" in str(path)
        assert not path.exists()   # the worktree is gone
    here = [row for row in result["rows"] if row["key"] == "warp_sim"]
    assert all(Path(row["warp_sim_path"]) == ROOT / "warp_sim" for row in here)
    assert "warp_sim-baseline-" not in git("worktree", "list", "--porcelain")
