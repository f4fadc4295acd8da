"""The PDC stacked on paper 000's PID/FLC: the hot path against scipy, the linear loop's promises, the spindle
hook and the live override, and refusals that name the parameter, the bound and the value."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from cnc_contour_control.axis.spindle_override import SpindleOverride, law_receiver
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.disturbance.loop import tf
from cnc_contour_control.disturbance.stack_loop import StackBlocks, pid_transfer, sampled_plant, stack_figures
from cnc_contour_control.laws import LawSample, law_config, make_law
from cnc_contour_control.laws.pdc_stack import PAPER000_X_MODEL, PdcStackLaw

DT_S = PAPER000_X_MODEL[2]
K_BLU_S, TAU_S = 28.35, 0.055  # paper 000's X drive, whose ZOH is the stacks' default P_n


@pytest.mark.parametrize(("name", "inner"), [("pid_pdc", "pid"), ("fuzzy_pdc", "fuzzy")])
def test_the_stack_is_the_inner_law_minus_h_on_the_model_residual_as_lfilter_computes_it(name: str,
                                                                                          inner: str) -> None:
    rng = np.random.default_rng(4)
    n = 200
    error, velocity, command = rng.normal(0, 5, n), rng.normal(0, 300, n), rng.normal(0, 40, n)
    law, alone = make_law(name, {}), make_law(inner, {})
    feedback, inner_feedback = [], []
    for k in range(n):
        applied = command[k - 1] if k else 0.0
        sample = LawSample(dt_s=DT_S, error_counts=error[k], velocity_counts_s=velocity[k], applied_command=applied)
        feedback.append(law.step(sample).feedback)
        inner_feedback.append(alone.step(sample).feedback)
    model = law.config.nominal()
    te = signal.lfilter(law.design.h, [1.0], velocity - signal.lfilter(model.numerator, model.denominator, command))
    np.testing.assert_allclose(feedback, np.array(inner_feedback) - te, rtol=1e-9, atol=1e-9)
    assert np.max(np.abs(te)) > 1.0, "the PDC acted (so the check can fail)"


def test_pid_transfer_is_the_pid_law() -> None:
    gains = {"kp": 2.4, "ki": 10.0, "kd": 0.067, "state_limit": 1.0e9}
    law = make_law("pid", gains)
    error = np.random.default_rng(2).normal(0, 3, 100)
    stepped = [law.step(LawSample(dt_s=DT_S, error_counts=e)).feedback for e in error]
    np.testing.assert_allclose(stepped, signal.lfilter(*pid_transfer(2.4, 10.0, 0.067, DT_S), error), rtol=1e-10)


def _blocks(gain_error: float, spindle_rpm: float) -> tuple[StackBlocks, float]:
    config = law_config("pid_pdc", {"spindle_rpm": spindle_rpm})
    velocity, position = sampled_plant((K_BLU_S * 1e-5 * (1 + gain_error),), (TAU_S, 1.0), 1.0e5, DT_S)
    model = config.nominal()
    return StackBlocks(velocity, position, tf(model.numerator, model.denominator),
                       pid_transfer(config.kp, config.ki, config.kd, DT_S), DT_S, tf(config.pdc_design().h)), \
        config.f_d_hz()


def test_with_the_exact_model_the_pdc_removes_f_d_and_leaves_s_alone_a_model_error_brings_it_in() -> None:
    exact = stack_figures(*_blocks(0.0, 150.0))
    assert exact["stable"] and exact["removal_at_fd"] == pytest.approx(1.0, abs=1e-6)
    assert exact["sensitivity_peak"] == pytest.approx(exact["sensitivity_peak_without"], rel=1e-9)
    assert exact["eq13_margin"] < 1e-9
    off = stack_figures(*_blocks(0.05, 150.0))
    assert off["removal_at_fd"] > 0.99 and off["sensitivity_peak"] != pytest.approx(off["sensitivity_peak_without"])
    assert 0.0 < off["eq13_margin"] < 1.0
    fast = stack_figures(*_blocks(0.05, 450.0))  # f_d 15 Hz at f_s 100 Hz: H reaches far beyond f_d
    assert fast["eq13_margin"] > 1.0 and not fast["stable"]


def test_the_spindle_hook_redesigns_and_a_speed_beyond_nyquist_keeps_the_last_design() -> None:
    law = make_law("pid_pdc", {"spindle_rpm": 150.0, "flutes": 4})
    assert isinstance(law, PdcStackLaw) and law.design.f_d_hz == pytest.approx(10.0)
    assert law.set_spindle_rpm(300.0) and law.design.f_d_hz == pytest.approx(20.0)
    assert not law.set_spindle_rpm(300.0)
    with pytest.raises(ConfigError, match=r"no design for spindle_rpm 750, keeping the one for 300 rpm: "
                                          r".*f_d_hz must be in \(0, 50\) Hz .* got 50"):
        law.set_spindle_rpm(750.0)
    assert law.design.f_d_hz == pytest.approx(20.0) and law.config.spindle_rpm == 300.0


@pytest.mark.parametrize(("params", "message"), [
    ({"spindle_rpm": 1500.0}, r"pid_pdc.spindle_rpm must be in \[1.0, 1400.0\], got 1500.0"),
    ({"model_numerator": [0.1, 4.7]}, r"pid_pdc.numerator must start with 1 zero coefficients, got \[0.1\]"),
    ({"spare_dof": "free"}, r"pid_pdc.spare_dof must be one of"),
    ({"model_sample_time_s": 0.5}, r"pid_pdc.model_sample_time_s must be in \[0.0001, 0.05\], got 0.5"),
    ({"flutes": 12, "spindle_rpm": 300.0}, r"pid_pdc.f_d_hz must be in \(0, 50\) Hz"),
])
def test_a_stack_that_cannot_be_designed_is_refused_naming_the_parameter(params: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        law_config("pid_pdc", params)


def test_the_live_override_goes_to_the_law_survives_a_retune_and_refuses_without_changing_anything() -> None:
    law = make_law("pid_pdc", {})
    override = SpindleOverride(law_receiver(law))
    assert override.set(300.0) is None and law.design.f_d_hz == pytest.approx(10.0)
    reason = override.set(1450.0)
    assert reason is not None and "spindle_rpm 1450 refused, keeping 300 rpm" in reason and "1400" in reason
    assert law.design.f_d_hz == pytest.approx(10.0) and override.rpm == 300.0
    law.retune(law_config("pid_pdc", {"kp": 3.0}))  # new gains carry the design speed, 150 rpm
    assert law.design.f_d_hz == pytest.approx(5.0)
    assert override.reapply() is None and law.design.f_d_hz == pytest.approx(10.0) and law.config.kp == 3.0
    assert "must be in [0, 1e+06], got -5.0" in override.set(-5.0)
    assert override.set(0.0) is None and override.rpm is None
    assert SpindleOverride(law_receiver(make_law("pid", {}))).set(1200.0) is None  # a law without a PDC ignores it
