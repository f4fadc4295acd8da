"""Paper 002's laws: a P position loop over the velocity-command plant plus disturbance paths.

One sample (counts and counts/s; the command is a velocity command)::

    u_nom(k−1) = v(k−1) + T_E(k−1) + d̂(k−1) − c(k−1)   the command without this law's corrections
    T_E(k) = H [y − P_n v](k)                            PDC (inner path), v = the applied command
    d̂(k)  = [Q P_n⁻¹] y(k) − [Q/z⁻¹] (u_nom − d̂)(k−1)   DOB (outer path)
    c(k)   = M [P_n u_nom − y](k)                        MBDA (outer path)
    feedback = k_p e(k) − d̂(k) − T_E(k) + c(k)

``y`` is the measured velocity, ``v`` the applied command (``LawSample.
applied_command``, after saturation and quantisation), P_n the nominal
closed velocity loop of :data:`~cnc_contour_control.core.velocity_models.
PAPER002_MODELS` (its one sample of delay makes every path causal). The
design (``cnc_contour_control.disturbance.design``) runs when the config is
built, so a config that cannot be designed (f_d at Nyquist, a bad L, an
RLS that does not converge, a Q of too low a relative degree) is refused
with the parameter, the bound and the value; :meth:`DisturbanceLaw.retune`
redesigns (a spindle override changes ``spindle_rpm``) and a refused config
never reaches it, so the running law keeps its last valid design;
:meth:`DisturbanceLaw.set_spindle_rpm` is the servo's per-tick hook for the
speed it commands (:class:`~cnc_contour_control.laws.base.SpindleFollowing`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from cnc_contour_control.core.config import require_choice, require_finite
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.core.velocity_models import PAPER002_MODELS, DiscreteVelocityModel
from cnc_contour_control.disturbance.design import (
    SPARE_DOF_CHOICES,
    PdcDesign,
    design_pdc,
    disturbance_frequency_hz,
    dob_filters,
    mbda_pi,
    q_filter,
    strip_delay,
)
from cnc_contour_control.disturbance.filters import FirFilter, IirFilter
from cnc_contour_control.disturbance.tracking import FrequencyTracker, TrackerConfig, tracked_rpm
from cnc_contour_control.laws.base import LawOutput, LawSample, require_config, spindle_redesign

#: Relative tolerance on a sample period against the model's.
PERIOD_TOLERANCE = 1e-6


@dataclass(frozen=True)
class PositionLoopConfig:
    """The P position loop and the nominal model shared by every paper-002 law.

    Parameters
    ----------
    kp : float
        Position gain K_pp [1/s] (velocity command per count of error), in [0, 1e4].
    model : str
        Nominal closed velocity loop P_n, a key of ``PAPER002_MODELS`` (Eqs. 35-36).
    """

    kp: float = param(30.0, unit="1/s", low=0.0, high=1.0e4, description="position gain K_pp")
    model: str = param("x", description=f"nominal velocity loop P_n, one of {sorted(PAPER002_MODELS)}")

    def nominal(self) -> DiscreteVelocityModel:
        """P_n."""
        return PAPER002_MODELS[self.model]

    def _validate(self, context: str) -> None:
        check_ranges(self, context)
        require_choice("model", self.model, PAPER002_MODELS, context)


@dataclass(frozen=True)
class DobConfig(PositionLoopConfig):
    """P loop + disturbance observer with the Umeno-Hori Q filter (Eq. 32, binomial coefficients).

    Parameters
    ----------
    q_order : int
        Order K of Q, in [1, 8].
    q_relative_degree : int
        Relative degree r of Q, in [1, 3]; must be >= the model's (1) and <= K.
    q_time_constant_s : float
        Time constant τ [s], in [1e-5, 10].
    """

    q_order: int = param(3, low=1, high=8, description="order K of the Q filter")
    q_relative_degree: int = param(1, low=1, high=3, description="relative degree r of Q (>= the model's, <= q_order)")
    q_time_constant_s: float = param(0.005, unit="s", low=1.0e-5, high=10.0, description="time constant of Q")

    def __post_init__(self) -> None:
        self._validate("dob")
        self.q_design()

    def q_design(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Q(z⁻¹) (refuses a relative degree below the model's)."""
        return q_filter(int(self.q_order), int(self.q_relative_degree), self.q_time_constant_s, self.nominal())


@dataclass(frozen=True)
class MbdaConfig(PositionLoopConfig):
    """P loop + model-based disturbance attenuator: PI M on model-minus-plant velocity.

    Parameters
    ----------
    mbda_kp : float
        Proportional gain of M [1] (velocity command per velocity), in [0, 1e3].
    mbda_ki : float
        Integral gain of M [1/s], in [0, 1e6].
    """

    mbda_kp: float = param(1.0, low=0.0, high=1.0e3, description="proportional gain of the MBDA's PI")
    mbda_ki: float = param(100.0, unit="1/s", low=0.0, high=1.0e6, description="integral gain of the MBDA's PI")

    def __post_init__(self) -> None:
        self._validate("mbda")


@dataclass(frozen=True)
class PdcConfig(PositionLoopConfig):
    """P loop + periodic disturbance canceller H = L·W designed for f_d = spindle_rpm·flutes/60.

    Parameters
    ----------
    spindle_rpm : float
        Spindle speed [rpm], in [1, 9000] (and f_d below Nyquist: the default 2 flutes give 300 Hz at most).
    flutes : int
        Cutting edges of the tool, in [1, 12].
    filter_order : int
        Order M of L; even and 4 × the number of zeros.
    zero_radii, zero_angles_pi : tuple of float
        L's zeros r_k e^{jπ a_k} (defaults: paper 002's, negated: angles 0.3, 0.57, 0.86).
    w_taps : int
        Taps N of W, in [2, 16].
    spare_dof : str
        ``"zero_dc"`` (W(1) = 0) or ``"rls"`` (the paper's RLS start decides).
    include_ml : bool
        Fit W against P_m = M_L z^−D_L P_n (True) or z^−D_L P_n (the reading that gives the paper's W).
    rls_delta : float
        R(0) = I/δ, in [1e-12, 1e-2].
    rls_samples : int
        Samples of s(n) for the RLS, in [100, 1e5].
    track_fd : bool
        Estimate f_d on line from the residual y − P_n v and redesign for it
        (``disturbance/tracking.py``), within ``track_band`` of the commanded speed.
    track_band : float
        Half-width of the tracked band, a fraction of the commanded f_d, in [0.01, 0.5].
    track_averaging_s : float
        Averaging time of the estimate [s], in [T, 10].
    track_min_amplitude : float
        Smallest f_d line of the residual that is tracked [counts/s], >= 0.
    """

    spindle_rpm: float = param(1500.0, unit="rpm", low=1.0, high=9000.0, description="spindle speed")
    flutes: int = param(2, low=1, high=12, description="cutting edges of the tool")
    filter_order: int = param(12, description="order M of the linear-phase low-pass L (even, 4 x the zeros)")
    zero_radii: tuple[float, ...] = param((0.9, 0.8, 0.85), description="radii r_k of L's zeros, each in (0, 1)")
    zero_angles_pi: tuple[float, ...] = param((0.3, 0.57, 0.86), unit="pi rad",
                                              description="angles of L's zeros (paper's printed ones negated)")
    w_taps: int = param(3, low=2, high=16, description="taps N of W")
    spare_dof: str = param("zero_dc", description=f"how W's spare degree of freedom is spent, {SPARE_DOF_CHOICES}")
    include_ml: bool = param(True, description="fit W against M_L z^-D_L P_n (False: z^-D_L P_n, the paper's W)")
    rls_delta: float = param(1.0e-5, low=1.0e-12, high=1.0e-2, description="RLS start R(0) = I/delta")
    rls_samples: int = param(2000, low=100, high=100000, description="samples of the RLS fit")
    track_fd: bool = param(False, description="estimate f_d on line from the residual and redesign for it")
    track_band: float = param(0.1, low=0.01, high=0.5, description="tracked band, fraction of the commanded f_d")
    track_averaging_s: float = param(0.1, unit="s", low=1.0e-3, high=10.0, description="averaging of the f_d estimate")
    track_min_amplitude: float = param(0.0, unit="count/s", low=0.0, high=1.0e9,
                                       description="smallest residual line at f_d that is tracked")

    def __post_init__(self) -> None:
        self._validate("pdc")
        for name in ("zero_radii", "zero_angles_pi"):
            values = getattr(self, name)
            if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
                raise ConfigError(f"pdc.{name} must be a list of numbers, got {values!r}")
            checked = tuple(require_finite(f"{name}[{i}]", v, "pdc") for i, v in enumerate(values))
            object.__setattr__(self, name, checked)
        self.pdc_design()
        if self.track_fd:
            self.tracker_config()

    def tracker_config(self) -> TrackerConfig:
        """The f_d tracker around the commanded f_d (validated: a band reaching Nyquist is refused)."""
        try:
            return TrackerConfig(self.f_d_hz(), self.nominal().sample_time_s, self.track_band,
                                 self.track_averaging_s, min_amplitude=self.track_min_amplitude)
        except ConfigError as err:
            raise ConfigError(f"pdc.track_band: {err}") from err

    def f_d_hz(self) -> float:
        """The disturbance frequency f_d [Hz] (Eq. 2)."""
        return disturbance_frequency_hz(self.spindle_rpm, int(self.flutes))

    def pdc_design(self) -> PdcDesign:
        """The design (cached), or a :class:`ConfigError` naming what refuses it."""
        if int(self.filter_order) % 2:
            raise ConfigError(f"pdc.filter_order must be even, got {self.filter_order}")
        angles = tuple(math.pi * a for a in self.zero_angles_pi)
        return design_pdc(self.nominal(), self.f_d_hz(), self.zero_radii, angles, int(self.filter_order),
                          int(self.w_taps), self.spare_dof, bool(self.include_ml), self.rls_delta,
                          int(self.rls_samples))


@dataclass(frozen=True)
class DobPdcConfig(PdcConfig, DobConfig):
    """P loop + PDC inside + DOB outside (paper 002 Fig. 4).

    W's spare degree of freedom defaults to the RLS's: with the DOB outside, W(1) = 0 raises the
    disturbance peak from 1.56 to 1.75 (2.03 at +20 % inertia; ``docs/paper002_design.md``).
    """

    spare_dof: str = param("rls", description=f"how W's spare degree of freedom is spent, {SPARE_DOF_CHOICES}")

    def __post_init__(self) -> None:
        self._validate("dob_pdc")
        DobConfig.__post_init__(self)
        PdcConfig.__post_init__(self)


@dataclass(frozen=True)
class MbdaPdcConfig(PdcConfig, MbdaConfig):
    """P loop + PDC inside + MBDA outside (paper 002 Fig. 6).

    W's spare degree of freedom defaults to the RLS's (disturbance peak 1.39 against 1.56 with W(1) = 0).
    """

    spare_dof: str = param("rls", description=f"how W's spare degree of freedom is spent, {SPARE_DOF_CHOICES}")

    def __post_init__(self) -> None:
        self._validate("mbda_pdc")
        PdcConfig.__post_init__(self)


def _delayed_model(model: DiscreteVelocityModel) -> IirFilter:
    """P_n/z⁻¹ as a filter: fed u(k−1), it gives [P_n u](k)."""
    return IirFilter(strip_delay(model.numerator, 1), model.denominator)


class DisturbanceLaw:
    """The P position loop with the disturbance paths its config selects (see the module docstring).

    Subclasses name the law and its config class; the config's type decides
    the paths (a :class:`DobPdcConfig` is both a :class:`DobConfig` and a
    :class:`PdcConfig`).
    """

    NAME = "disturbance"
    CONFIG: type = PositionLoopConfig

    def __init__(self, config: PositionLoopConfig) -> None:
        self.output = LawOutput()
        self._key: dict[str, object] = {}
        self._h: FirFilter | None = None
        self._tracker: FrequencyTracker | None = None
        self.tracked_redesigns = self.tracking_refusals = 0
        self.retune(config)
        self.reset()

    def retune(self, config: PositionLoopConfig) -> None:
        """New gains; a changed design swaps filters (H keeps its input history: a spindle change is bumpless).

        The config was designed when it was built, so a design that fails never gets here and the law keeps
        its last valid one.
        """
        self.config = require_config(self.NAME, config, self.CONFIG)
        self._kp = config.kp
        model = config.nominal()
        self._dt_s = self.sample_time_s = model.sample_time_s  # the design's period: the law runs at no other
        self._retune_pdc(config, model)
        self._retune_tracker(config)
        self._retune_dob(config, model)
        self._retune_mbda(config, model)

    def set_spindle_rpm(self, spindle_rpm: float) -> bool:
        """Redesign the PDC for ``spindle_rpm`` [rpm] if it differs from the design's (see :class:`SpindleFollowing`).

        A law without a PDC ignores the spindle (False). The new config is built
        (and so designed) before anything changes: a refused speed raises its
        :class:`ConfigError` and the law keeps its last valid design.
        """
        if not isinstance(self.config, PdcConfig):
            return False
        redesigned = spindle_redesign(self.NAME, self.config, spindle_rpm)
        if redesigned is None:
            return False
        self.retune(redesigned)
        return True

    def _changed(self, path: str, key: object) -> bool:
        if self._key.get(path) == key:
            return False
        self._key[path] = key
        return True

    def _retune_pdc(self, config: PositionLoopConfig, model: DiscreteVelocityModel) -> None:
        if not isinstance(config, PdcConfig):
            return
        self.design = config.pdc_design()
        self.design_rpm = config.spindle_rpm
        if self._changed("pdc_model", model):
            self._pdc_model = _delayed_model(model)
        if self._h is None:
            self._h = FirFilter(self.design.h)
        else:
            self._h.set_taps(self.design.h)

    def _retune_tracker(self, config: PositionLoopConfig) -> None:
        """A tracker around the commanded f_d (a new one when the commanded speed or its settings change)."""
        if not isinstance(config, PdcConfig) or not config.track_fd:
            self._tracker = None
            return
        tracker = config.tracker_config()
        if self._tracker is None or self._tracker.config != tracker:
            self._tracker = FrequencyTracker(tracker)

    def _track(self, residual: float) -> None:
        """Step the tracker; redesign H for the estimated speed when it leaves the design (tracking.tracked_rpm)."""
        assert self._tracker is not None and isinstance(self.config, PdcConfig)
        estimate = self._tracker.step(residual)
        if estimate is None:
            return
        rpm = tracked_rpm(self.config.spindle_rpm, self._tracker.config.center_hz, estimate, self.design_rpm)
        if rpm is None:
            return
        try:
            self._retune_pdc(replace(self.config, spindle_rpm=rpm, track_fd=False), self.config.nominal())
        except ConfigError:
            self.tracking_refusals += 1  # no design for that speed: the law keeps its last one
            return
        self.tracked_redesigns += 1

    def _retune_dob(self, config: PositionLoopConfig, model: DiscreteVelocityModel) -> None:
        self._dob = isinstance(config, DobConfig)
        if isinstance(config, DobConfig) and self._changed("dob", (model, config.q_design())):
            inverse, shifted = dob_filters(config.q_design(), model)
            self._q_inverse, self._q_command = IirFilter(*inverse), IirFilter(*shifted)

    def _retune_mbda(self, config: PositionLoopConfig, model: DiscreteVelocityModel) -> None:
        self._mbda = isinstance(config, MbdaConfig)
        if isinstance(config, MbdaConfig) and self._changed("mbda", (model, config.mbda_kp, config.mbda_ki)):
            self._mbda_model = _delayed_model(model)
            self._m = IirFilter(*mbda_pi(config.mbda_kp, config.mbda_ki, self._dt_s))

    def reset(self) -> None:
        """Zero every filter, the f_d tracker's state and the previous corrections (H keeps its last design)."""
        for name in ("_pdc_model", "_h", "_q_inverse", "_q_command", "_mbda_model", "_m", "_tracker"):
            flt = getattr(self, name, None)
            if flt is not None:
                flt.reset()
        self._te = self._dh = self._c = 0.0

    def step(self, sample: LawSample) -> LawOutput:
        """One sample (see the module docstring); a period other than the model's is a :class:`FaultError`."""
        if abs(sample.dt_s - self._dt_s) > PERIOD_TOLERANCE * self._dt_s:
            raise FaultError(f"{self.NAME}: dt_s must be the model's sample time {self._dt_s:g} s, got {sample.dt_s!r}")
        y, v = sample.velocity_counts_s, sample.applied_command
        u_nom = v + self._te + self._dh - self._c
        te = 0.0
        if self._h is not None:
            residual = y - self._pdc_model.step(v)
            te = self._h.step(residual)
            if self._tracker is not None:
                self._track(residual)
        dh = self._q_inverse.step(y) - self._q_command.step(v + self._te) if self._dob else 0.0
        c = self._m.step(self._mbda_model.step(u_nom) - y) if self._mbda else 0.0
        self._te, self._dh, self._c = te, dh, c
        out = self.output
        out.feedback = self._kp * sample.error_counts - dh - te + c
        out.disturbance_estimate = dh + te - c
        return out


class DobLaw(DisturbanceLaw):
    """P loop + DOB."""

    NAME, CONFIG = "dob", DobConfig


class MbdaLaw(DisturbanceLaw):
    """P loop + MBDA."""

    NAME, CONFIG = "mbda", MbdaConfig


class PdcLaw(DisturbanceLaw):
    """P loop + PDC."""

    NAME, CONFIG = "pdc", PdcConfig


class DobPdcLaw(DisturbanceLaw):
    """P loop + PDC inside, DOB outside."""

    NAME, CONFIG = "dob_pdc", DobPdcConfig


class MbdaPdcLaw(DisturbanceLaw):
    """P loop + PDC inside, MBDA outside."""

    NAME, CONFIG = "mbda_pdc", MbdaPdcConfig
