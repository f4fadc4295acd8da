"""Tier 1: the configs' declared ranges are their validation, at the bounds, for every config class."""
from __future__ import annotations

import math
from typing import Any

import pytest

from cnc_contour_control.axis.servo import ServoConfig

#: Every config class a node declares parameters from, with the required fields it needs to build.
from cnc_contour_control.compensators import COMPENSATORS, compensator_config_class
from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import ParamSpec, config_values, declared_bounds, flat_specs
from cnc_contour_control.estimators import ESTIMATORS, estimator_config_class
from cnc_contour_control.graph.stage_params import (
    CompensatorRunParams,
    EstimatorRunParams,
    InterpolatorRunParams,
    ServoRunParams,
    servo_config_values,
)
from cnc_contour_control.laws import LAWS, law_config_class
from cnc_contour_control.motion.axis_limits import AxisLimits
from cnc_contour_control.motion.interpolator_config import InterpolatorConfig
from cnc_plant_sim.models.axis import AxisConfig
from cnc_plant_sim.models.plant import PLANTS, PlantConfig, VariationConfig
from cnc_plant_sim.run.run_params import PlantRunParams

CONFIGS: dict[type, dict[str, Any]] = {
    InterpolatorConfig: {},
    AxisLimits: {"max_velocity_m_s": (0.1, 0.2), "max_acceleration_m_s2": (1.0, 2.0)},
    InterpolatorRunParams: {},
    ServoConfig: {"axis_name": "x"},
    ServoRunParams: {"input_timeout_s": 0.01, "startup_timeout_s": 3600.0},  # startup >= input at every bound
    PlantConfig: {},
    VariationConfig: {},
    AxisConfig: {"name": "x", "gain_blu_s_per_dac": 28.35, "time_constant_s": 0.055},
    PlantRunParams: {"command_timeout_s": 0.01, "startup_timeout_s": 3600.0},
    **{law_config_class(name): {} for name in LAWS},
    **{estimator_config_class(name): {} for name in ESTIMATORS},
    **{compensator_config_class(name): {} for name in COMPENSATORS if name != "none"},  # none: no fields
    EstimatorRunParams: {"input_timeout_s": 0.01, "startup_timeout_s": 3600.0},
    CompensatorRunParams: {"input_timeout_s": 0.01, "startup_timeout_s": 3600.0},
}


def _with(base: dict[str, Any], dotted: str, value: Any) -> dict[str, Any]:
    """``base`` with the (possibly nested) field ``dotted`` set to ``value``."""
    mapping: dict[str, Any] = {**base}
    level = mapping
    *parents, leaf = dotted.split(".")
    for part in parents:
        level[part] = dict(level.get(part, {}))
        level = level[part]
    level[leaf] = value
    return mapping


def _outside(spec: ParamSpec, bound: float, direction: float) -> float:
    """The first value beyond ``bound`` (the next float, or the next integer)."""
    return bound + direction if spec.kind is int else math.nextafter(bound, direction * math.inf)


def _model_base(cls: type, base: dict[str, Any], spec: ParamSpec) -> dict[str, Any]:
    """A plant config's base with the model whose own section holds ``spec`` (a plant takes its model's only)."""
    models = [name for name, entry in PLANTS.items() if entry.section == spec.name.split(".")[0]]
    return {**base, "model": models[0]} if cls is PlantConfig and models else base


def _bounds() -> list[Any]:
    return [pytest.param(cls, _model_base(cls, base, spec), spec, bound, direction,
                         id=f"{cls.__name__}.{spec.name}{'<' if direction < 0 else '>'}")
            for cls, base in CONFIGS.items() for spec, bound, direction in declared_bounds(cls)]


@pytest.mark.parametrize(("cls", "base", "spec", "bound", "direction"), _bounds())
def test_a_declared_bound_is_accepted_and_the_next_value_beyond_refused_naming_it(
        cls: type, base: dict[str, Any], spec: ParamSpec, bound: float, direction: float) -> None:
    value = int(bound) if spec.kind is int else float(bound)
    config = build_config(cls, _with(base, spec.name, value))
    leaf = spec.name.rsplit(".", 1)[-1]
    assert getattr(_field_owner(config, spec.name), leaf) == value
    with pytest.raises(ConfigError, match=leaf):
        build_config(cls, _with(base, spec.name, _outside(spec, bound, direction)))


def _field_owner(config: Any, dotted: str) -> Any:
    for part in dotted.split(".")[:-1]:
        config = getattr(config, part)
    return config


def test_every_config_class_has_declared_fields_and_its_defaults_build() -> None:
    for cls, base in CONFIGS.items():
        specs = flat_specs(cls)
        assert specs and all(s.info.description for s in specs), cls.__name__
        build_config(cls, base)


@pytest.mark.parametrize("cls", list(CONFIGS), ids=lambda c: c.__name__)
def test_config_values_build_the_same_config_again(cls: type) -> None:
    config = build_config(cls, CONFIGS[cls])
    assert build_config(cls, config_values(config)) == config


def test_nested_sections_are_dotted_names() -> None:
    names = [s.name for s in flat_specs(PlantConfig)]
    assert {"variation.gain_pct", "variation.time_constant_pct", "variation.friction_pct"} <= set(names)
    assert "variation" not in names


def test_the_servo_node_values_are_the_config_values_with_law_params_as_gains() -> None:
    config = ServoConfig.from_mapping({"axis_name": "y", "law": "pid", "law_params": {"kp": 3.0}})
    values = servo_config_values(config)
    assert values["gains"] == {"kp": 3.0} and "axis_name" not in values and "law_params" not in values
    assert {k: v for k, v in values.items() if k != "gains"} == {
        k: v for k, v in config_values(config).items() if k not in ("axis_name", "law_params")}
