"""``limits.max_jerk_mm_s3`` in a scenario: parsed per axis or once, refused naming the option, and planned with."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.motion.reference_check import limit_ratios
from cnc_tools.runs.graph_nodes import graph_specs
from cnc_tools.runs.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]
PERIOD_S = 1e-3


def _scenario(tmp_path: Path, jerk: object) -> Path:
    raw = yaml.safe_load((ROOT / "scenarios" / "paper000_corner_low.yaml").read_text())
    raw["limits"]["max_jerk_mm_s3"] = jerk
    path = tmp_path / "jerk.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize(("jerk", "expected_m_s3"), [(10000, (10.0, 10.0)), ([5000, 20000], (5.0, 20.0))])
def test_jerk_limit_is_planned_with_on_every_sample(tmp_path: Path, jerk: object,
                                                    expected_m_s3: tuple[float, float]) -> None:
    scenario = load_scenario(_scenario(tmp_path, jerk))
    assert scenario.limits.max_jerk_m_s3 == pytest.approx(expected_m_s3)
    interpolator = scenario.make_interpolator()
    times = np.arange(-3 * PERIOD_S, interpolator.duration_s + 3 * PERIOD_S, PERIOD_S)
    ratios = limit_ratios(interpolator.sample_array(times).position_m, PERIOD_S, scenario.limits)
    assert ratios.worst() <= 1.0 + 1e-9
    assert ratios.jerk.max() > 0.5   # the jerk limit is what shapes the profile


def test_without_the_option_the_limits_have_no_jerk(tmp_path: Path) -> None:
    raw = yaml.safe_load((ROOT / "scenarios" / "paper000_corner_low.yaml").read_text())
    assert "max_jerk_mm_s3" not in raw["limits"]
    assert load_scenario(ROOT / "scenarios" / "paper000_corner_low.yaml").limits.max_jerk_m_s3 is None


def test_graph_parameters_carry_the_jerk_limit_only_when_set(tmp_path: Path) -> None:
    with_jerk = load_scenario(_scenario(tmp_path, 10000))
    plain = load_scenario(ROOT / "scenarios" / "paper000_corner_low.yaml")
    for scenario, present in ((with_jerk, True), (plain, False)):
        specs = graph_specs(scenario, tmp_path)
        params = [spec.parameters for spec in specs if "interpolator" in spec.name]
        assert params and ("max_jerk_m_s3" in params[0]) is present


@pytest.mark.parametrize(("jerk", "words"), [
    (-1, ["scenario.limits.max_jerk_mm_s3", "> 0", "-1"]),
    ([1000, 2000, 3000], ["scenario.limits.max_jerk_mm_s3", "1 or 2 values", "3"]),
    ("fast", ["scenario.limits.max_jerk_mm_s3", "'fast'"])])
def test_bad_jerk_limits_are_refused_naming_the_option(tmp_path: Path, jerk: object, words: list[str]) -> None:
    with pytest.raises(ConfigError) as caught:
        load_scenario(_scenario(tmp_path, jerk))
    for word in words:
        assert word in str(caught.value), (word, str(caught.value))
