"""The servo follows the spindle speed it commands: the PDC redesigns on line, a refused speed keeps the design."""
from __future__ import annotations

import numpy as np
import pytest

from cnc_contour_control.axis.servo import ServoConfig, ServoController
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws import LawSample, make_law
from cnc_contour_control.laws.base import SpindleFollowing
from cnc_contour_control.laws.disturbance import DisturbanceLaw

SERVO = {"axis_name": "x", "counts_per_m": 1.0, "output_limit": 1.0, "quantum": 0.0, "command_unit": "m/s"}


def _pdc(law: str = "pdc", flutes: int = 2) -> DisturbanceLaw:
    found = make_law(law, {"kp": 40.0, "spindle_rpm": 1500.0, "flutes": flutes})
    assert isinstance(found, DisturbanceLaw)
    return found


def _warm(law: DisturbanceLaw, steps: int = 50) -> None:
    sample = LawSample(dt_s=1e-3, applied_command=2e-3)
    for k in range(steps):
        sample.velocity_counts_s = 2e-3 + 1e-4 * np.sin(2 * np.pi * 0.05 * k)
        law.step(sample)


@pytest.mark.parametrize("name", ["pdc", "dob_pdc", "mbda_pdc"])
def test_a_pdc_law_redesigns_for_a_new_speed_keeping_its_filter_history(name: str) -> None:
    law = _pdc(name)
    _warm(law)
    h_filter, before = law._h, law.design.h
    history = np.array(list(h_filter._x))
    assert np.any(history != 0.0), "a warm filter"
    assert isinstance(law, SpindleFollowing)
    assert law.set_spindle_rpm(1650.0) is True
    assert law.config.spindle_rpm == 1650.0 and law.design.f_d_hz == pytest.approx(55.0)
    assert not np.allclose(law.design.h, before), "the taps changed"
    assert law._h is h_filter, "the same filter object: its input history stays"
    np.testing.assert_array_equal(np.array(list(h_filter._x)), history)
    assert law.set_spindle_rpm(1650.0) is False, "the same speed: no redesign"


def test_a_law_without_a_pdc_ignores_the_spindle() -> None:
    law = make_law("dob", {"kp": 40.0})
    assert isinstance(law, DisturbanceLaw) and law.set_spindle_rpm(1650.0) is False


@pytest.mark.parametrize(("rpm", "flutes", "words"), [
    (20000.0, 2, r"spindle_rpm must be in \[1.0, 9000.0\], got 20000"),
    (0.5, 2, r"spindle_rpm must be in \[1.0, 9000.0\], got 0.5"),
    (4000.0, 8, r"below Nyquist at T = 0.001 s"),
])
def test_a_refused_speed_names_it_and_keeps_the_last_design(rpm: float, flutes: int, words: str) -> None:
    law = _pdc(flutes=flutes)
    law.set_spindle_rpm(1650.0)
    design, config = law.design, law.config
    with pytest.raises(ConfigError, match=words) as refused:
        law.set_spindle_rpm(rpm)
    assert f"{rpm:g}" in str(refused.value) and "keeping the one for 1650 rpm" in str(refused.value)
    assert law.design is design and law.config is config


def _controller(times_s: tuple[float, ...], rpms: tuple[float, ...], law: str = "mbda_pdc") -> ServoController:
    return ServoController(ServoConfig.from_mapping({**SERVO, "law": law, "law_params": {"kp": 40.0},
                                                     "spindle_schedule_t_s": list(times_s),
                                                     "spindle_schedule_rpm": list(rpms)}))


def test_the_servo_redesigns_at_the_tick_of_the_change_and_reports_a_refusal_once() -> None:
    servo = _controller((0.0, 0.002, 0.004), (1500.0, 20000.0, 1350.0))
    law = servo.law
    assert isinstance(law, DisturbanceLaw) and servo.spindle is not None
    seen = {}
    for k in range(6):
        stamp_ns = k * 1_000_000
        seen[k] = servo.follow_spindle(stamp_ns)
        if k == 2:
            assert seen[k] is not None and "spindle_rpm must be in [1.0, 9000.0], got 20000" in seen[k]
            assert law.config.spindle_rpm == 1500.0, "the refused speed keeps the design"
        servo.parts(1e-3, 0.0, 2e-3, 0.0, 0.0, 2e-3, 0.0)
    assert [k for k, reason in seen.items() if reason] == [2], "refused once, at its tick"
    assert law.config.spindle_rpm == 1350.0 and servo.spindle.redesigns == 1


def test_a_retune_keeps_the_commanded_speed() -> None:
    servo = _controller((0.0,), (1650.0,))
    servo.follow_spindle(0)
    gains = ServoConfig.from_mapping({**SERVO, "law": "mbda_pdc", "law_params": {"kp": 30.0},
                                      "spindle_schedule_t_s": [0.0], "spindle_schedule_rpm": [1650.0]})
    servo.retune(gains)
    assert servo.law.config.kp == 30.0 and servo.law.config.spindle_rpm == 1650.0


def test_a_law_that_does_not_follow_the_spindle_gets_no_follower() -> None:
    servo = _controller((0.0,), (1650.0,), law="p")
    assert servo.spindle is None and servo.follow_spindle(0) is None


@pytest.mark.parametrize(("times", "rpms", "words"), [
    ([0.0, 0.1], [1500.0], "spindle_schedule_rpm must have one entry per spindle_schedule_t_s (2), got 1"),
    ([0.2, 0.1], [1500.0, 1600.0], "spindle_schedule_t_s[1] must be > 0.2, got 0.1"),
    ([-0.1], [1500.0], "spindle_schedule_t_s[0] must be >= 0, got -0.1"),
    ([0.0], [0.0], "spindle_schedule_rpm[0] must be > 0, got 0"),
    ([0.0], [float("nan")], "spindle_schedule_rpm must hold finite numbers"),
    ("0.1", [1500.0], "spindle_schedule_t_s must be a list of numbers"),
])
def test_a_bad_schedule_is_refused_naming_the_option_bound_and_value(times: object, rpms: object, words: str) -> None:
    with pytest.raises(ConfigError, match=words.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(")
                       .replace(")", r"\)")):
        ServoConfig.from_mapping({**SERVO, "law": "pdc", "law_params": {"kp": 40.0},
                                  "spindle_schedule_t_s": times, "spindle_schedule_rpm": rpms})
