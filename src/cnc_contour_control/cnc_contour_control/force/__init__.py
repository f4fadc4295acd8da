"""Cutting-force regulation through the feed override (paper 004): model, laws, switch, regulator (ROS-free)."""
from __future__ import annotations

from cnc_contour_control.core.force_model import DepthSchedule, FirstOrderLag, TurningModelConfig
from cnc_contour_control.force.base import ForceLaw, check_sample
from cnc_contour_control.force.preview import PreviewConfig, StepPlan, plan_schedule, plan_step
from cnc_contour_control.force.quantiser import Quantiser, QuantiserConfig
from cnc_contour_control.force.registry import FORCE_LAWS, ForceLawEntry, force_law_config, make_force_law
from cnc_contour_control.force.regulator import ForceRegulator, ForceRegulatorConfig, OverrideSample

__all__ = ["FORCE_LAWS", "DepthSchedule", "FirstOrderLag", "ForceLaw", "ForceLawEntry", "ForceRegulator",
           "ForceRegulatorConfig", "OverrideSample", "PreviewConfig", "Quantiser", "QuantiserConfig", "StepPlan",
           "TurningModelConfig", "check_sample", "force_law_config", "make_force_law", "plan_schedule", "plan_step"]
