"""benchmarks/gradients.py --quick: its table and its JSON (a 16 x 16 cloth's drape gradient over 1 s against the
forward run). Nothing about times."""
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_quick_benchmark_prints_its_table_and_writes_its_json(tmp_path):
    out = tmp_path / "gradients.json"
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gradients.py"), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    header = next(line for line in lines if line.startswith("| cloth |"))
    for column in ("forward [s]", "forward peak growth [MB]", "gradient [s]", "gradient peak growth [MB]",
                   "stored states [MB]"):
        assert column in header
    assert any(line.startswith("| 16² | 480 |") for line in lines)
    result = json.loads(out.read_text())
    assert (result["resolution"], result["frames"], result["steps"], result["particles"]) == (16, 60, 480, 256)
    assert result["gradient"]["finite"]
    assert abs(result["forward"]["drape_m"] - result["gradient"]["drape_m"]) < 1e-12   # the same run (sums apart)
    stored = result["stored"]
    assert stored["states_mb"] == 61 * 256 * 6 * 8 / 2**20 and stored["pool_states"] >= 16
    assert 0.0 <= result["gradient"]["peak_growth_mb"] < 600.0
    print(header, next(line for line in lines if line.startswith("| 16² |")), sep="\n")
