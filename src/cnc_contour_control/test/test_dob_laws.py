"""Paper 002's laws in closed loop with the linear plant, against the python-control loop of the report."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.velocity_models import PAPER002_MODELS
from cnc_contour_control.disturbance.filters import IirFilter
from cnc_contour_control.disturbance.loop import inertia_perturbed, tf
from cnc_contour_control.laws import LAWS, LawSample, law_config, make_law
from cnc_contour_control.laws.disturbance import PositionLoopConfig
from cnc_contour_control.laws.loop_report import design_report, loop_figures

T_S = 0.001
COMBINATIONS = ("dob", "mbda", "pdc", "dob_pdc", "mbda_pdc")


def _simulate(law, ticks: int, f_d_hz: float = 50.0, inertia_error: float = 0.0, friction: float = 20.0,
              amplitude: float = 100.0, spindle_step=None) -> np.ndarray:
    """Positions [counts] of the loop law + plant, disturbance friction + amplitude·sin(2π f_d t) at the input."""
    model = PAPER002_MODELS["x"]
    b, a = inertia_perturbed(tf(model.numerator, model.denominator), inertia_error)
    plant = IirFilter(b[1:], a)  # y(k) from v(k−1): the plant's own sample of delay
    sample, x, y, v, xs = LawSample(dt_s=T_S), 0.0, 0.0, 0.0, []
    for k in range(ticks):
        if spindle_step is not None and k == spindle_step[0]:
            law.retune(spindle_step[1])
            f_d_hz = spindle_step[1].f_d_hz()
        sample.error_counts, sample.velocity_counts_s, sample.position_counts, sample.applied_command = -x, y, x, v
        v = law.step(sample).feedback
        y_last, y = y, plant.step(v + friction + amplitude * math.sin(2.0 * math.pi * f_d_hz * (k + 1) * T_S))
        x += 0.5 * T_S * (y_last + y)  # the trapezoid rule, as the paper002 plant
        xs.append(x)
    return np.array(xs)


def _lock_in(x: np.ndarray, f_hz: float) -> float:
    """Amplitude of the f_hz component of ``x`` (whole periods assumed)."""
    t = np.arange(len(x)) * T_S
    return float(2.0 * abs(np.mean((x - x.mean()) * np.exp(-2j * np.pi * f_hz * t))))


def test_the_five_combinations_are_registered() -> None:
    for name in COMBINATIONS:
        assert name in LAWS
        assert make_law(name).config.kp == pytest.approx(30.0)


@pytest.mark.parametrize("name", COMBINATIONS)
@pytest.mark.parametrize("inertia_error", [0.0, 0.2])
def test_law_matches_the_linear_loop(name: str, inertia_error: float) -> None:
    """The f_d component removed in closed loop is the report's removal at f_d (python-control's loop)."""
    bare = _simulate(make_law("p", {"kp": 30.0}), 2000, inertia_error=inertia_error)[1000:]
    ours = _simulate(make_law(name), 2000, inertia_error=inertia_error)[1000:]
    removal = 1.0 - _lock_in(ours, 50.0) / _lock_in(bare, 50.0)
    expected = loop_figures(law_config(name), 50.0, inertia_error, points=50)["removal_at_fd"]
    assert removal == pytest.approx(expected, abs=0.01)


def test_dob_estimates_the_constant_disturbance() -> None:
    law = make_law("dob")
    positions = _simulate(law, 1500, amplitude=0.0)
    assert law.output.disturbance_estimate == pytest.approx(20.0, rel=1e-3)
    assert abs(positions[-1]) < 1e-3  # no steady error left by the friction


def test_spindle_override_redesigns_and_the_pdc_follows() -> None:
    law = make_law("pdc")
    faster = law_config("pdc", {"spindle_rpm": 1575.0})  # +5 %
    positions = _simulate(law, 3000, spindle_step=(1000, faster))
    assert law.design.f_d_hz == pytest.approx(52.5)
    bare = _simulate(make_law("p", {"kp": 30.0}), 3000, f_d_hz=52.5)
    assert _lock_in(positions[2000:], 52.5) < 0.05 * _lock_in(bare[2000:], 52.5)


def test_refused_redesign_keeps_the_last_design() -> None:
    law = make_law("pdc")
    before = law.design
    with pytest.raises(ConfigError, match="f_d_hz must be in"):
        law.retune(law_config("pdc", {"spindle_rpm": 2500.0, "flutes": 12}))  # f_d = 500 Hz
    assert law.design is before
    with pytest.raises(ConfigError, match="pdc law needs a PdcConfig"):
        law.retune(law_config("dob"))


def test_a_period_other_than_the_models_is_a_fault() -> None:
    with pytest.raises(FaultError, match="dt_s must be the model's sample time 0.001 s, got 0.002"):
        make_law("mbda").step(LawSample(dt_s=0.002))


def test_design_report_per_combination() -> None:
    configs = {"none": PositionLoopConfig(), **{name: law_config(name) for name in COMBINATIONS}}
    report = design_report(configs, 50.0, points=200)
    for name, entry in report.items():
        for loop in entry["loops"]:
            assert loop["stable"], (name, loop)
            if "pdc" in name:
                assert loop["removal_at_fd"] > 0.95
                assert loop["disturbance_peak"] <= 2.0, (name, loop)
        if "pdc" in name:
            pdc = entry["pdc"]
            assert pdc["hp_gain_at_fd"] == pytest.approx(1.0, abs=0.01)
            assert abs(pdc["hp_phase_deg_at_fd"]) < 1.0
            assert max(pdc["eq13_margin"].values()) < 1.0  # Eq. 13 holds for a ±20 % inertia error
    assert report["none"]["loops"][0]["removal_at_fd"] == pytest.approx(0.0, abs=1e-9)


def test_servo_retunes_the_spindle_and_refuses_a_bad_one() -> None:
    """What the servo node does on a parameter set: build the config (refused with a reason), then retune."""
    from cnc_contour_control.axis.servo import ServoConfig, ServoController

    def config(spindle_rpm: float) -> ServoConfig:
        return ServoConfig.from_mapping({"axis_name": "x", "law": "dob_pdc", "law_params": {"spindle_rpm": spindle_rpm},
                                         "quantum": 0.0, "output_limit": 1.0e9, "counts_per_m": 2.4e6})

    servo = ServoController(config(1500.0))
    servo.step(T_S, 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0)
    servo.retune(config(1700.0))
    assert servo.law.design.f_d_hz == pytest.approx(1700.0 * 2 / 60.0)
    with pytest.raises(ConfigError, match="spindle_rpm must be in"):
        config(9500.0)
    assert servo.law.design.f_d_hz == pytest.approx(1700.0 * 2 / 60.0)


def test_frequency_responses_for_the_figures() -> None:
    from cnc_contour_control.laws.loop_report import pdc_frequency_responses

    curves = pdc_frequency_responses(law_config("pdc"), points=500)
    at_fd = int(np.argmin(np.abs(curves["f_hz"] - 50.0)))
    assert curves["f_hz"][at_fd] == pytest.approx(50.0, abs=0.5)
    assert abs(curves["hp"][at_fd]) == pytest.approx(1.0, abs=0.02)
    assert np.allclose(curves["hp"], curves["l"] * curves["w"] * curves["pn"])
    assert abs(curves["l"][-1]) < 0.05  # L is a low-pass
