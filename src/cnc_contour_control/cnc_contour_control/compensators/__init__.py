"""Cross-axis compensators (stage 4 of the tick): the seam (:mod:`.base`) and the registry :data:`COMPENSATORS`."""
from __future__ import annotations

from cnc_contour_control.compensators.base import (
    Compensator,
    CompensatorSample,
    NoCompensatorConfig,
    ZeroCompensator,
    check_sample,
)
from cnc_contour_control.compensators.cross_coupled import CrossCoupledCompensator, CrossCoupledConfig
from cnc_contour_control.compensators.ilc import IlcConfig, IterativeLearningCompensator
from cnc_contour_control.compensators.neural import NeuralCompensator, NeuralConfig
from cnc_contour_control.compensators.registry import (
    COMPENSATORS,
    CompensatorEntry,
    compensator_config,
    compensator_config_class,
    make_compensator,
)
from cnc_contour_control.compensators.state_file import load_state, save_state

__all__ = ["COMPENSATORS", "Compensator", "CompensatorEntry", "CompensatorSample", "CrossCoupledCompensator",
           "CrossCoupledConfig", "IlcConfig", "IterativeLearningCompensator", "NeuralCompensator", "NeuralConfig",
           "NoCompensatorConfig", "ZeroCompensator", "check_sample", "compensator_config",
           "compensator_config_class", "load_state", "make_compensator", "save_state"]
