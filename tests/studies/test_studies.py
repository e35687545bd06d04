"""The accuracy and stability studies (warp_sim.studies), run quick: observed orders, the intermediate-axis
period, stability limits against theory, reports, the command line and bad input."""
import csv
import math
import sys

import pytest

import warp_sim as ws
from warp_sim import studies
from warp_sim.cli import main
from warp_sim.studies.problems import flip_period, intermediate_axis_period, pendulum_period

EXPLICIT_ORDERS = {"euler": 1, "midpoint": 2, "rk4": 4, "symplectic_euler": 1, "verlet": 2}


def test_observed_orders_on_the_oscillator():
    result = studies.accuracy(problems=["oscillator"], integrators=list(EXPLICIT_ORDERS), quick=True, repeats=1)
    for integrator, expected in EXPLICIT_ORDERS.items():
        assert result.order("oscillator", integrator) == pytest.approx(expected, abs=0.2), integrator
    assert {row["integrator"] for row in result.rows} == set(EXPLICIT_ORDERS)
    assert all(row["seconds_per_simulated_second"] > 0 and row["error"] < 0.2 for row in result.rows)


def test_closed_form_periods():
    assert pendulum_period(math.radians(170.0)) == pytest.approx(4.8935242741, abs=1e-9)
    assert intermediate_axis_period() == pytest.approx(22.99626, abs=5e-6)


def test_rk4_flip_period_of_the_intermediate_axis():
    """rk4 at h = 1e-3: the simulated Dzhanibekov flip period within 0.5 % of 22.99626 s."""
    assert flip_period("rk4", 1e-3) == pytest.approx(22.99626, rel=5e-3)


def test_single_spring_limits_match_theory():
    result = studies.stability(cases=["spring_1e4"], integrators=["rk4", "symplectic_euler", "verlet"], quick=True)
    omega = 100.0
    assert result.limit("spring_1e4", "rk4") * omega == pytest.approx(2.0 * math.sqrt(2.0), rel=0.02)
    assert result.limit("spring_1e4", "symplectic_euler") * omega == pytest.approx(2.0, rel=0.02)
    assert result.limit("spring_1e4", "verlet") * omega == pytest.approx(2.0, rel=0.02)


def test_cloth_limit_of_symplectic_euler():
    """The 12 x 12 lattice with k = 100 N/m and m = 0.01 kg: 0.6285 sqrt(m/k) within 5 %."""
    result = studies.stability(cases=["cloth"], integrators=["symplectic_euler"], quick=True)
    assert result.limit("cloth", "symplectic_euler") / math.sqrt(0.01 / 100.0) == pytest.approx(0.6285, rel=0.05)


def test_accuracy_report_csv_and_plots(tmp_path):
    """Every integrator by default (rk45, where present, driven by its tolerance); CSV, markdown, PNGs."""
    result = studies.accuracy(problems=["projectile"], quick=True, repeats=1)
    assert {row["integrator"] for row in result.rows} == set(ws.INTEGRATORS)
    for row in result.rows:
        assert row["knob"] == ("rtol" if row["integrator"] == "rk45" else "h")
    images = result.plot(tmp_path)
    assert [p.name for p in images] == ["accuracy_projectile.png"] and images[0].stat().st_size > 0
    result.to_csv(tmp_path / "accuracy.csv")
    with open(tmp_path / "accuracy.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == len(result.rows) and {"error", "seconds_per_simulated_second", "h"} <= set(rows[0])
    text = result.to_markdown(tmp_path / "accuracy.md", images=images).read_text()
    assert "## Observed orders" in text and "](accuracy_projectile.png)" in text and "| verlet | exact |" in text


def test_stability_report_and_plots_without_matplotlib(tmp_path, monkeypatch):
    result = studies.stability(cases=["zero_rest_length"], integrators=["symplectic_euler", "implicit_euler"],
                               quick=True)
    assert result.limit("zero_rest_length", "symplectic_euler") * 100.0 == pytest.approx(2.0, rel=0.02)
    assert [d["amplitude_per_step"] for d in result.damping] == pytest.approx([d["theory"] for d in result.damping],
                                                                              rel=1e-3)
    assert {p.name for p in result.plot(tmp_path)} == {"stability_cases.png", "stability_damping.png"}
    result.to_csv(tmp_path / "stability.csv")
    assert "zero_rest_length" in result.to_markdown(tmp_path / "stability.md").read_text()
    for module in ("matplotlib", "matplotlib.figure", "matplotlib.backends.backend_agg"):
        monkeypatch.setitem(sys.modules, module, None)     # import fails: plots are skipped
    assert result.plot(tmp_path / "none") == []


def test_command_line(tmp_path, capsys):
    out = tmp_path / "acc"
    assert main(["study", "accuracy", "--quick", "--problems", "projectile", "--integrators", "verlet",
                 "--out", str(out), "--quiet"]) == 0
    assert {p.name for p in out.iterdir()} >= {"accuracy.md", "accuracy.csv"}
    out = tmp_path / "stab"
    assert main(["study", "stability", "--quick", "--cases", "zero_rest_length", "--integrators", "verlet",
                 "--out", str(out), "--quiet"]) == 0
    assert {p.name for p in out.iterdir()} >= {"stability.md", "stability.csv"}
    assert "wrote" in capsys.readouterr().out


@pytest.mark.slow   # both quick studies whole: about a minute
@pytest.mark.parametrize("study, names", [("accuracy", "PROBLEMS"), ("stability", "CASES")])
def test_quick_study_command_runs_whole(tmp_path, study, names):
    """What CI runs: each study command in its --quick mode over every problem or case and integrator."""
    out = tmp_path / study
    assert main(["study", study, "--quick", "--out", str(out), "--quiet"]) == 0
    report = (out / f"{study}.md").read_text()
    for name in getattr(studies, names):
        if not name.startswith("spring_"):   # the single springs form one table, by ks/m
            assert name in report
    assert any(p.suffix == ".png" for p in out.iterdir())


@pytest.mark.parametrize("call, argument, shown", [
    (lambda: studies.accuracy(problems=["nope"]), "problems", "nope"),
    (lambda: studies.accuracy(integrators=["rk5"]), "integrators", "rk5"),
    (lambda: studies.accuracy(steps=[]), "steps", "[]"),
    (lambda: studies.accuracy(steps=[0.01, -1.0]), "steps", "-1.0"),
    (lambda: studies.accuracy(tolerances=[1e-6, 0.0]), "tolerances", "0.0"),
    (lambda: studies.accuracy(repeats=0), "repeats", "0"),
    (lambda: studies.stability(cases=["nope"]), "cases", "nope"),
    (lambda: studies.stability(integrators=["nope"]), "integrators", "nope"),
])
def test_bad_input_names_the_argument_value_and_what_is_valid(call, argument, shown):
    with pytest.raises(ValueError) as caught:
        call()
    message = str(caught.value)
    assert message.startswith(f"{argument}=") and shown in message and ("expected" in message or "must" in message)


@pytest.mark.skipif("rk45" not in ws.INTEGRATORS, reason="no adaptive integrator registered")
def test_adaptive_solver_is_not_bisected():
    with pytest.raises(ValueError, match="integrators=.*rk45.*fixed-step"):
        studies.stability(cases=["spring_1e4"], integrators=["rk45"])

def test_frame_rate_stack_limit_is_above_the_default_contact_step():
    """The stability study's stack of ten, under symplectic Euler without sub-steps: it stands (no box moves 5 mm
    in 10 s) up to a step above 1/120 s, the Simulator's default contact_step (measured: 0.0107 s), and falls
    within the search (the bisection brackets the limit to 1 %)."""
    result = studies.stability(cases=["stack_10"], integrators=["symplectic_euler"], quick=True)
    row = result.rows[0]
    assert row["limit"] > 1.0 / 120.0
    assert row["unstable"] < 0.25 and row["unstable"] / row["limit"] < 1.01
