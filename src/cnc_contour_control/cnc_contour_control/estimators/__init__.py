"""Contour-error estimators (ROS-free): the seam (:mod:`.base`) and the registry :data:`ESTIMATORS`
(:mod:`.registry`)."""
from __future__ import annotations

from cnc_contour_control.estimators.base import ContourEstimate, ContourEstimator
from cnc_contour_control.estimators.path import (
    PathEstimator,
    PathEstimatorConfig,
    signed_contour_error,
    signed_segment_error,
)
from cnc_contour_control.estimators.registry import (
    ESTIMATORS,
    EstimatorEntry,
    estimator_config,
    estimator_config_class,
    make_estimator,
)
from cnc_contour_control.estimators.window import WindowEstimator, WindowEstimatorConfig

__all__ = ["ESTIMATORS", "ContourEstimate", "ContourEstimator", "EstimatorEntry", "PathEstimator",
           "PathEstimatorConfig", "WindowEstimator", "WindowEstimatorConfig", "estimator_config",
           "estimator_config_class", "make_estimator", "signed_contour_error", "signed_segment_error"]
