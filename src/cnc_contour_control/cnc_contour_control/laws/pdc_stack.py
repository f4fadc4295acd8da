"""Paper 002's periodic disturbance canceller stacked on a law that is no velocity-command cascade (ROS-free).

Paper 002 puts the PDC inside a P position loop over a closed velocity loop;
here it sits on any law of the registry (paper 000's PID and FLC, paper 001's
PID), whose command is a drive input (DAC, N) and whose plant is the drive
itself. One sample (law units: velocity in counts/s, command in drive units)::

    u_in(k) = inner law's feedback                 (its own state, unchanged)
    T_E(k)  = H [y − P_n v](k)                     v: the applied command, y: the measured velocity
    feedback = u_in(k) − T_E(k)

P_n is the plant from the drive input to the axis velocity in law units,
given as z⁻¹ coefficients at the servo's sample time (``model_numerator``,
``model_denominator``, ``model_sample_time_s``, numerator[0] = 0: the command
acts one sample later); :mod:`cnc_plant_sim.models.nominal_models` derives it from a
plant config (ZOH of the drive's transfer function, scipy.signal). H = L·W is
:func:`~cnc_contour_control.disturbance.design.design_pdc`'s, with L, W's
taps and the RLS settings at :class:`~cnc_contour_control.laws.disturbance.
PdcConfig`'s defaults (one declaration). If y − P_n v = P_n d (the model
holds), T_E = H P_n d ≈ d at f_d and the load's f_d line leaves the command.

A config that cannot be designed (f_d at or above Nyquist at the model's
sample time, an RLS that misses) is refused when built, so the running law
keeps its last valid design (:meth:`PdcStackLaw.set_spindle_rpm`, the servo's
spindle hook).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.config import require_choice, require_finite
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.velocity_models import DiscreteVelocityModel
from cnc_contour_control.disturbance.design import (
    SPARE_DOF_CHOICES,
    PdcDesign,
    design_pdc,
    disturbance_frequency_hz,
    strip_delay,
)
from cnc_contour_control.disturbance.filters import FirFilter, IirFilter
from cnc_contour_control.laws.base import LawOutput, LawSample, require_config, spindle_redesign
from cnc_contour_control.laws.disturbance import PERIOD_TOLERANCE, PdcConfig
from cnc_contour_control.laws.fuzzy import FuzzyConfig, FuzzyLaw
from cnc_contour_control.laws.pid import PidConfig, PidLaw

#: L, W's taps and the RLS settings of every stack: PdcConfig's defaults.
PDC_DEFAULTS: dict[str, Any] = {f.name: f.default for f in dataclasses.fields(PdcConfig)}
#: Default P_n: paper 000's X drive, K = 28.35 BLU/s per DAC, τ = 0.055 s, ZOH at T = 10 ms (BLU/s per DAC):
#: b_1 = K (1 − e^(−T/τ)), a_1 = −e^(−T/τ) (``nominal_models.paper000_velocity_model`` derives it; a test checks).
PAPER000_X_POLE = math.exp(-0.01 / 0.055)
PAPER000_X_MODEL = ((0.0, 28.35 * (1.0 - PAPER000_X_POLE)), (1.0, -PAPER000_X_POLE), 0.01)


@dataclass(frozen=True)
class CancellerConfig:
    """The PDC of a stack: the spindle, the flutes, the plant model P_n and W's spare degree of freedom.

    Parameters
    ----------
    spindle_rpm : float
        Spindle speed [rpm], in [1, 1400] (and f_d below Nyquist at ``model_sample_time_s``: 1400 rpm with
        2 flutes is 46.7 Hz, designable at the default 10 ms; more flutes reach higher f_d at faster rates).
    flutes : int
        Cutting edges of the tool, in [1, 12].
    model_numerator, model_denominator : tuple of float
        P_n in z⁻¹, drive units -> counts/s (numerator[0] = 0, denominator[0] = 1).
    model_sample_time_s : float
        The sample time of P_n and of the law [s], in [1e-4, 0.05].
    spare_dof : str
        ``"zero_dc"`` (W(1) = 0: H leaves DC to the inner law) or ``"rls"``.
    """

    spindle_rpm: float = param(150.0, unit="rpm", low=1.0, high=1400.0, description="spindle speed of the design")
    flutes: int = param(2, low=1, high=12, description="cutting edges of the tool")
    model_numerator: tuple[float, ...] = param(PAPER000_X_MODEL[0], unit="(count/s)/drive",
                                               description="P_n numerator in z^-1 (first 0: one-sample delay)")
    model_denominator: tuple[float, ...] = param(PAPER000_X_MODEL[1], description="P_n denominator in z^-1 (first 1)")
    model_sample_time_s: float = param(PAPER000_X_MODEL[2], unit="s", low=1.0e-4, high=0.05,
                                       description="sample time of P_n and of the law")
    spare_dof: str = param("zero_dc", description=f"how W's spare degree of freedom is spent, {SPARE_DOF_CHOICES}")

    def _validate_canceller(self, context: str) -> None:
        require_choice("spare_dof", self.spare_dof, SPARE_DOF_CHOICES, context)
        for name in ("model_numerator", "model_denominator"):
            values = getattr(self, name)
            if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
                raise ConfigError(f"{context}.{name} must be a list of numbers, got {values!r}")
            object.__setattr__(self, name, tuple(require_finite(f"{name}[{i}]", v, context)
                                                 for i, v in enumerate(values)))
        try:
            strip_delay(self.model_numerator, 1)
            self.pdc_design()
        except ConfigError as err:
            raise ConfigError(f"{context}.{err}") from err

    def nominal(self) -> DiscreteVelocityModel:
        """P_n."""
        return DiscreteVelocityModel(self.model_numerator, self.model_denominator, self.model_sample_time_s)

    def f_d_hz(self) -> float:
        """f_d = spindle_rpm · flutes / 60 [Hz]."""
        return disturbance_frequency_hz(self.spindle_rpm, int(self.flutes))

    def pdc_design(self) -> PdcDesign:
        """The design (cached by ``design_pdc``), or a :class:`ConfigError` naming what refuses it."""
        d = PDC_DEFAULTS
        angles = tuple(math.pi * a for a in d["zero_angles_pi"])
        return design_pdc(self.nominal(), self.f_d_hz(), d["zero_radii"], angles, int(d["filter_order"]),
                          int(d["w_taps"]), self.spare_dof, bool(d["include_ml"]), d["rls_delta"],
                          int(d["rls_samples"]))


@dataclass(frozen=True)
class PidPdcConfig(PidConfig, CancellerConfig):
    """Paper 000's incremental PID (its gains) with the PDC on top."""

    def __post_init__(self) -> None:
        check_ranges(self, "pid_pdc")
        self._validate_canceller("pid_pdc")


@dataclass(frozen=True)
class FuzzyPdcConfig(FuzzyConfig, CancellerConfig):
    """Paper 000's FLC (its tables) with the PDC on top."""

    def __post_init__(self) -> None:
        check_ranges(self, "fuzzy_pdc")
        FuzzyConfig.__post_init__(self)
        self._validate_canceller("fuzzy_pdc")


class PdcStackLaw:
    """An inner law with the PDC's T_E subtracted from its feedback (see the module docstring)."""

    NAME = "pdc_stack"
    CONFIG: type = CancellerConfig
    INNER: type = PidLaw

    def __init__(self, config: CancellerConfig) -> None:
        self.output = LawOutput()
        self.inner = self.INNER(config)
        self._h: FirFilter | None = None
        self._model_key: DiscreteVelocityModel | None = None
        self.retune(config)
        self.reset()

    def retune(self, config: CancellerConfig) -> None:
        """New gains for both; a changed design swaps H's taps keeping its input history (bumpless)."""
        self.config = require_config(self.NAME, config, self.CONFIG)
        self.inner.retune(config)
        model = config.nominal()
        self.sample_time_s = model.sample_time_s
        self.design = config.pdc_design()
        if model != self._model_key:
            self._model, self._model_key = IirFilter(strip_delay(model.numerator, 1), model.denominator), model
        if self._h is None:
            self._h = FirFilter(self.design.h)
        else:
            self._h.set_taps(self.design.h)

    def set_spindle_rpm(self, spindle_rpm: float) -> bool:
        """Redesign for ``spindle_rpm`` [rpm] if it differs (see :class:`~cnc_contour_control.laws.base.
        SpindleFollowing`); a refused speed raises its :class:`ConfigError` and nothing changes."""
        redesigned = spindle_redesign(self.NAME, self.config, spindle_rpm)
        if redesigned is None:
            return False
        self.retune(redesigned)
        return True

    def reset(self) -> None:
        """The inner law's state, H's and P_n's histories to zero."""
        self.inner.reset()
        self._model.reset()
        if self._h is not None:
            self._h.reset()

    def step(self, sample: LawSample) -> LawOutput:
        """One sample; a period other than the model's is a :class:`FaultError`."""
        if abs(sample.dt_s - self.sample_time_s) > PERIOD_TOLERANCE * self.sample_time_s:
            raise FaultError(f"{self.NAME}: dt_s must be the model's sample time {self.sample_time_s:g} s, "
                             f"got {sample.dt_s!r}")
        inner = self.inner.step(sample)
        h = self._h  # retune(), which __init__ calls, sets it
        te = h.step(sample.velocity_counts_s - self._model.step(sample.applied_command))  # type: ignore[union-attr]  # see above
        out = self.output
        out.feedback = inner.feedback - te
        out.disturbance_estimate = inner.disturbance_estimate + te
        return out


class PidPdcLaw(PdcStackLaw):
    """PID + PDC."""

    NAME, CONFIG, INNER = "pid_pdc", PidPdcConfig, PidLaw


class FuzzyPdcLaw(PdcStackLaw):
    """FLC + PDC."""

    NAME, CONFIG, INNER = "fuzzy_pdc", FuzzyPdcConfig, FuzzyLaw
