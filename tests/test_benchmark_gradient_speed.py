"""benchmarks/gradient_speed.py --quick: its two tables and its JSON (ws.gradient against the forward run on cloths,
a pile and a throw; Newton's differentiable cloth beside warp_sim's where Newton imports), the gradients finite, the
throw's against its closed form and Newton's against warp_sim's. Nothing about times."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import gradient_speed  # noqa: E402


def test_the_throws_closed_form_is_its_own_derivative():
    """throw_closed_form's d (w . p(T)) / d (vx, vy) against central differences of its own landing position (the
    formula differentiated by hand, checked on the formula; d/dvz, the friction turning a sideways throw, is held to
    the run's gradient below)."""
    throw = gradient_speed.THROW
    closed = gradient_speed.throw_closed_form()
    assert 0.0 < closed["impact_time"] < gradient_speed.THROW_SECONDS
    step = 1e-6
    for k in (0, 1):
        losses = []
        for sign in (1.0, -1.0):
            velocity = list(throw["velocity"])
            velocity[k] += sign * step
            losses.append(gradient_speed.throw_closed_form(throw_={**throw, "velocity": tuple(velocity)})["loss"])
        assert (losses[0] - losses[1]) / (2.0 * step) == pytest.approx(closed["d_loss_d_velocity"][k], rel=1e-7)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("gradient_speed") / "gradient_speed.json"
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gradient_speed.py"), "--quick", "--out",
                           str(out)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.splitlines(), json.loads(out.read_text())


def test_the_quick_run_prints_its_tables(quick):
    lines, _ = quick
    header = next(line for line in lines if line.startswith("| scene |"))
    for column in ("steps", "forward [s]", "of it, making the Simulator [s]", "forward + backward (ws.gradient) [s]",
                   "gradient / forward"):
        assert column in header
    for row in ("| cloth 8² | 240 |", "| cloth 16² | 240 |", "| pile of 8 spheres | 240 |",
                "| ball throw (1 particle) | 480 |"):
        assert any(line.startswith(row) for line in lines), row
    newton = next(line for line in lines if line.startswith("| cloth (float32) |"))
    assert "Newton gradient / forward" in newton and "warp_sim / Newton, gradient" in newton
    assert sum(line.startswith("| cloth 8² |") for line in lines) == 2   # a row in each table
    first = lines.index(header)
    print(*lines[first:first + 6], sep="\n")


def test_the_quick_json_holds_finite_gradients_of_the_same_runs(quick):
    _, result = quick
    assert (result["mode"], result["repeats"], result["fps"], result["substeps"]) == ("quick", 1, 60.0, 8)
    rows = {row["key"]: row for row in result["rows"]}
    assert list(rows) == ["cloth8", "cloth16", "pile", "throw"]
    for key, row in rows.items():
        assert row["status"] == "ok", row["status"]
        assert len(row["forward"]["seconds"]) == len(row["gradient"]["seconds"]) == len(row["forward"]["build_s"]) == 1
        assert 0.0 < row["forward"]["build_s"][0] < row["forward"]["seconds"][0]
        assert row["gradient"]["finite"], key
        assert row["ratio"] > 0.0
    assert (rows["cloth16"]["particles"], rows["cloth16"]["steps"], rows["pile"]["bodies"]) == (256, 240, 8)
    assert rows["cloth16"]["gradient"]["shape"] == [rows["cloth16"]["springs"]]
    for key in ("cloth8", "cloth16", "throw"):   # the forward run and the gradient's: the same run
        assert abs(rows[key]["forward"]["loss"] - rows[key]["gradient"]["loss"]) < 1e-12, key
    # the pile: a differentiable run does every resting iteration, a forward run stops at its tolerance
    assert abs(rows["pile"]["forward"]["loss"] - rows["pile"]["gradient"]["loss"]) < 1e-4
    assert rows["cloth16"]["gradient"]["d_drape_d_log_stiffness"] > 0.0   # stiffer: it hangs higher
    assert rows["pile"]["gradient"]["shape"] == [8, 3]


def test_the_throw_has_its_closed_forms_gradient(quick):
    """rk4 integrates the parabola exactly and the plane pass bounces it at its time of impact: the run is the
    closed form's, and so is its gradient (through the friction's cut of the tangential speed too)."""
    _, result = quick
    throw = next(row for row in result["rows"] if row["key"] == "throw")
    closed = throw["gradient"]["closed_form"]
    assert abs(throw["forward"]["loss"] - closed["loss"]) < 1e-9
    np.testing.assert_allclose(throw["gradient"]["d_loss_d_velocity"], closed["d_loss_d_velocity"], atol=1e-6)
    assert throw["gradient"]["closed_form_error"] < 1e-9   # what it measures: 2e-14
    assert abs(closed["d_loss_d_velocity"][1]) > 0.1      # the bounce matters


def test_newton_and_warp_sim_differentiate_the_same_cloth(quick):
    _, result = quick
    if result["newton"]["version"] is None:
        assert all(row["status"].startswith("n/a (") for row in result["newton_cloth"])
        pytest.skip(f"newton: {result['newton']['status']}")
    for row in result["newton_cloth"]:
        assert row["status"] == "ok", row["status"]
        assert row["precision"] == "float32" and row["steps"] == 240
        assert row["warp_sim"]["finite"] and row["newton"]["finite"]
        assert abs(row["warp_sim"]["loss"] - row["newton"]["loss"]) < 1e-5   # float32 sums apart
        assert row["d_log_stiffness_relative_difference"] < 1e-3          # measured 3e-9 to 3e-7
        assert row["gradient_relative_difference"] < 1e-3
        assert all(0.0 < b < f for b, f in zip(row["seconds"]["newton_build"], row["seconds"]["newton_forward"]))
        for key in ("warp_sim_gradient_over_forward", "newton_gradient_over_forward",
                    "warp_sim_over_newton_gradient", "warp_sim_over_newton_forward"):
            assert row[key] > 0.0
