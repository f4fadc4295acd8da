"""Radius reduction of a circular test: Eqs. 12-13's prediction against closed forms, and a recorded run."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.ballbar_radius import RadiusLossModel, model_from_scenario, predict_radius_loss
from cnc_tools.cli.main import main

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
FEED_M_S, RADIUS_M = 4000 / 60e3, 0.01


def test_small_lags_give_eq13_and_the_first_order_lag_of_eq12() -> None:
    model = RadiusLossModel(position_gain_per_s=300.0, accel_decel_kind="exponential",
                            accel_decel_time_constant_s=0.002)
    loss = predict_radius_loss(model, FEED_M_S, RADIUS_M)
    assert loss.accel_decel_um == pytest.approx(loss.accel_decel_eq13_um, rel=1e-3)
    assert loss.servo_lag_um == pytest.approx((FEED_M_S / 300.0) ** 2 / (2 * RADIUS_M) * 1e6, rel=1e-3)
    both = 1 - (1 - loss.servo_lag_um / 1e4) * (1 - loss.accel_decel_um / 1e4)
    assert loss.total_um == pytest.approx(both * 1e4)


def test_linear_accel_decel_is_a_twelfth_of_the_exponential() -> None:
    linear = predict_radius_loss(RadiusLossModel(None, 0.0, "linear", 0.002), FEED_M_S, RADIUS_M)
    exponential = predict_radius_loss(RadiusLossModel(None, 0.0, "exponential", 0.002), FEED_M_S, RADIUS_M)
    assert linear.accel_decel_um == pytest.approx(exponential.accel_decel_um / 12, rel=1e-2)
    assert linear.servo_lag_um is None and linear.total_um is None


def test_full_velocity_feedforward_removes_the_servo_lag() -> None:
    loss = predict_radius_loss(RadiusLossModel(30.0, feedforward=1.0), FEED_M_S, RADIUS_M)
    assert loss.servo_lag_um == pytest.approx(0.0, abs=1e-9) and loss.accel_decel_um == 0.0


def test_the_servo_lag_is_predicted_only_for_a_p_loop_on_a_velocity_commanded_plant() -> None:
    paper003 = model_from_scenario(yaml.safe_load((SCENARIOS / "paper003_circle.yaml").read_text()))
    assert paper003.position_gain_per_s == pytest.approx(30.0) and paper003.accel_decel_kind == "exponential"
    paper000 = model_from_scenario(yaml.safe_load((SCENARIOS / "paper000_circle_high.yaml").read_text()))
    assert paper000.position_gain_per_s is None and "law p" in paper000.skipped


def test_bad_models_are_refused() -> None:
    with pytest.raises(ConfigError, match="accel_decel_kind"):
        RadiusLossModel(30.0, accel_decel_kind="cubic")
    with pytest.raises(ConfigError, match="position_gain_per_s"):
        RadiusLossModel(-1.0)


def test_a_recorded_paper003_circle_shows_the_predicted_loss(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    assert main(["run", str(SCENARIOS / "paper003_circle.yaml"), "--engine", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["circular", str(out / "bag")]) == 0
    rows = {line.split()[0]: line.split()[1] for line in capsys.readouterr().out.splitlines() if "_um " in line}
    predicted = float(rows["ccw.radius_loss_predicted_um"])
    measured = float(rows["ccw.radius_loss_measured_um"])
    expected = predict_radius_loss(RadiusLossModel(30.0, 0.0, "exponential", 0.01), FEED_M_S, RADIUS_M)
    assert predicted == pytest.approx(expected.total_um, rel=1e-5)
    # one revolution from rest: the start transient keeps the mean below the steady loss, never above it
    assert 0.6 * predicted < measured < 1.02 * predicted
    assert not math.isnan(measured)
