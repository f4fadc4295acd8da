"""Fuzzy logic servo law of paper 000 (PD-type FLC plus an integral term).

The law is ``u(k) = u_scale * F[e_scale * e(k), de_scale * de(k)] + u_I(k)``
with the error rate ``de(k) = (e(k) - e(k-1)) / T_k`` and ``u_I(k) = u_I(k-1) +
ki * T_k * e(k)`` clamped to ``+-integral_limit`` (paper 000, Eqs. 3-8, in time
units; ``T_k`` is the sample's ``dt_s``). ``F`` uses seven fuzzy sets per
variable (NL NM NS ZR PS PM PL): triangles whose feet sit at the neighbours'
centres, shoulders beyond NL and PL, Mamdani min inference and the simplified
centre-of-area defuzzification of Eq. 8. Because neighbouring triangles form a
partition of unity, each input lies in at most two sets and at most four rules
fire; ``F`` locates the two active sets by bisection and never loops over the
49 rules.

Units: the error is in the law's length unit (counts; BLU = 10 um for paper
000), the error rate in counts/s, the output in drive units (DAC). ``ki`` is
per second. The paper defines the law per sample (``de`` the change over one
sample, ``ki`` per sample) at T = 0.01 s; its Table 3 change-of-error centres
(+-1.5, 3, 4.5 BLU per sample) and Table 4's ``ki = 0.1`` per sample are the
defaults here as rates: +-150, 300, 450 BLU/s and ``ki = 10 /s``
(:func:`fuzzy_params_from_per_sample` converts), so at T = 10 ms the law is the
paper's, to rounding, and at another T it keeps the same map of error and
error rate.

``cnc-contour bench laws`` measures the cost per step beside the PID's and
prints the equivalent gains of every rule base beside the paper's Table 4
(:mod:`cnc_contour_control.laws.fuzzy_gains`).
"""
from __future__ import annotations

import dataclasses
from bisect import bisect_right
from collections.abc import Mapping, Sequence
from typing import Any

from cnc_contour_control.core.config import require_finite, require_positive
from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.laws.base import LawOutput, LawSample, require_config

#: Names of the seven fuzzy sets, from most negative to most positive.
SET_NAMES: tuple[str, ...] = ("NL", "NM", "NS", "ZR", "PS", "PM", "PL")
N_SETS = len(SET_NAMES)

RuleBase = tuple[tuple[str, ...], ...]
RuleBaseSpec = str | Sequence[Sequence[str]]

#: Paper 000's sample time [s]: its Table 3 and 4 values are per sample at this T.
PAPER000_SAMPLE_TIME_S = 0.01
#: Paper 000, Table 3: centres of the change of error, BLU per sample (at T = 10 ms).
PAPER000_DE_CENTRES_PER_SAMPLE: tuple[float, ...] = (-4.5, -3.0, -1.5, 0.0, 1.5, 3.0, 4.5)
#: Range of the input and output scales (dimensionless).
SCALE_RANGE = (1.0e-9, 1.0e9)


def fuzzy_params_from_per_sample(params: Mapping[str, Any], sample_time_s: float) -> dict[str, Any]:
    """FLC params given per sample at ``sample_time_s`` [s] (as paper 000's tables) in this law's units.

    ``de_centres`` (change per sample) become rates (divided by T) and ``ki``
    (per sample) becomes per second (divided by T); every other key is kept.
    ``{"de_centres": PAPER000_DE_CENTRES_PER_SAMPLE, "ki": 0.1}`` at 0.01 s gives
    the defaults of :class:`FuzzyConfig`.
    """
    period = require_positive("sample_time_s", sample_time_s)
    out = dict(params)
    if "de_centres" in out:
        out["de_centres"] = tuple(float(c) / period for c in out["de_centres"])
    if "ki" in out:
        out["ki"] = float(out["ki"]) / period
    return out


def _rows(*rows: str) -> RuleBase:
    return tuple(tuple(row.split()) for row in rows)


#: Rule bases of paper 000, Table 1 (rows e = NL..PL, columns de = NL..PL).
#: The extraction lost the de = NL column of the non-constant rows; see
#: docs/fuzzy_rule_base.md for the reconstruction and the alternatives.
RULE_BASES: dict[str, RuleBase] = {
    # Lost column de = NL, filled so that C(-e, -de) = -C(e, de) (preferred).
    "paper000": _rows(
        "NL NL NL NL NL NL NL",
        "NL NL NM NM NS NS NS",
        "NL NM NM NS NS NS ZR",
        "ZR ZR ZR ZR ZR ZR ZR",
        "ZR PS PS PS PM PM PL",
        "PS PS PS PM PM PL PL",
        "PL PL PL PL PL PL PL",
    ),
    # Lost column de = NL, filled by repeating each row's first survivor.
    "paper000_alt_a": _rows(
        "NL NL NL NL NL NL NL",
        "NL NL NM NM NS NS NS",
        "NM NM NM NS NS NS ZR",
        "ZR ZR ZR ZR ZR ZR ZR",
        "PS PS PS PS PM PM PL",
        "PS PS PS PM PM PL PL",
        "PL PL PL PL PL PL PL",
    ),
    # Lost column de = ZR, filled with the row's own set (C(e, ZR) = e).
    "paper000_alt_b": _rows(
        "NL NL NL NL NL NL NL",
        "NL NM NM NM NS NS NS",
        "NM NM NS NS NS NS ZR",
        "ZR ZR ZR ZR ZR ZR ZR",
        "PS PS PS PS PM PM PL",
        "PS PS PM PM PM PL PL",
        "PL PL PL PL PL PL PL",
    ),
    # Lost column de = PL (the survivors are the first six), last entry repeated.
    # Its equivalent P gain (3.0) contradicts Table 4 (2.4); kept for sensitivity.
    "paper000_alt_c": _rows(
        "NL NL NL NL NL NL NL",
        "NL NM NM NS NS NS NS",
        "NM NM NS NS NS ZR ZR",
        "ZR ZR ZR ZR ZR ZR ZR",
        "PS PS PS PM PM PL PL",
        "PS PS PM PM PL PL PL",
        "PL PL PL PL PL PL PL",
    ),
}


def _check_rule_base(value: RuleBaseSpec) -> RuleBase:
    """Return ``value`` as a 7x7 tuple of set names, or raise naming the bad row or entry."""
    if isinstance(value, str):
        if value not in RULE_BASES:
            raise ConfigError(
                f"rule_base must be one of {sorted(RULE_BASES)} or a 7x7 table, got {value!r}"
            )
        return RULE_BASES[value]
    if not isinstance(value, Sequence) or len(value) != N_SETS:
        shape = len(value) if isinstance(value, Sequence) else type(value).__name__
        raise ConfigError(f"rule_base must have {N_SETS} rows (e = NL..PL), got {shape}")
    return tuple(_check_rule_row(i, row) for i, row in enumerate(value))


def _check_rule_row(i: int, row: Any) -> tuple[str, ...]:
    where = f"rule_base row {i} (e = {SET_NAMES[i]})"
    if isinstance(row, str) or not isinstance(row, Sequence) or len(row) != N_SETS:
        shape = len(row) if isinstance(row, Sequence) and not isinstance(row, str) else repr(row)
        raise ConfigError(f"{where} must have {N_SETS} entries (de = NL..PL), got {shape}")
    for j, name in enumerate(row):
        if name not in SET_NAMES:
            raise ConfigError(
                f"rule_base[{i}][{j}] (e = {SET_NAMES[i]}, de = {SET_NAMES[j]}) must be one of "
                f"{list(SET_NAMES)}, got {name!r}"
            )
    return tuple(row)


def _check_centres(name: str, value: Sequence[float]) -> tuple[float, ...]:
    """Return ``value`` as 7 strictly increasing finite floats, or raise naming the index."""
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) != N_SETS:
        raise ConfigError(f"{name} must have {N_SETS} values (NL..PL), got {value!r}")
    centres = tuple(require_finite(f"{name}[{k}]", v) for k, v in enumerate(value))
    for k in range(1, N_SETS):
        if not centres[k] > centres[k - 1]:
            raise ConfigError(
                f"{name} must be strictly increasing: {name}[{k}] = {centres[k]} "
                f"must be > {name}[{k - 1}] = {centres[k - 1]}"
            )
    return centres


@dataclasses.dataclass(frozen=True)
class FuzzyConfig:
    """Configuration of the FLC of paper 000 (defaults: Tables 1, 3 and 4, in time units at T = 10 ms).

    Attributes
    ----------
    e_centres : tuple of 7 float
        Centres of NL..PL for the error, in law length units (counts; BLU).
    de_centres : tuple of 7 float
        Centres for the error rate, counts/s (Table 3's +-1.5, 3, 4.5 BLU per sample / 10 ms).
    u_centres : tuple of 7 float
        Centres of the output sets, in drive units (DAC).
    rule_base : 7x7 tuple of set names, or a key of ``RULE_BASES``
        Output set of each rule; rows e = NL..PL, columns de = NL..PL.
    e_scale, de_scale : float
        Input scaling factors in [1e-9, 1e9]: ``F`` sees ``e_scale * e`` and ``de_scale * de``.
    u_scale : float
        Output scaling factor in [1e-9, 1e9] applied to ``F``.
    ki : float
        Integral gain, drive units per count-second, in [0, 1e6] (Eq. 3; Table 4's 0.1 per sample is 10 /s).
    integral_limit : float
        Anti-windup clamp of the integral term, drive units, in [0, 1e12].
    """

    e_centres: tuple[float, ...] = param((-21.0, -14.0, -7.0, 0.0, 7.0, 14.0, 21.0), unit="count",
                                         description="centres of the error sets NL..PL, strictly increasing")
    de_centres: tuple[float, ...] = param((-450.0, -300.0, -150.0, 0.0, 150.0, 300.0, 450.0), unit="count/s",
                                          description="centres of the error-rate sets NL..PL, strictly increasing")
    u_centres: tuple[float, ...] = param((-55.0, -35.0, -15.0, 0.0, 15.0, 35.0, 55.0), unit="drive",
                                         description="centres of the output sets NL..PL, strictly increasing")
    rule_base: RuleBaseSpec = param("paper000", description=f"rule base: one of {sorted(RULE_BASES)} "
                                    "or a 7x7 table of set names (rows e, columns de)")
    e_scale: float = param(1.0, low=SCALE_RANGE[0], high=SCALE_RANGE[1], description="error input scale")
    de_scale: float = param(1.0, low=SCALE_RANGE[0], high=SCALE_RANGE[1], description="error-rate input scale")
    u_scale: float = param(1.0, low=SCALE_RANGE[0], high=SCALE_RANGE[1], description="output scale")
    ki: float = param(10.0, unit="drive/(count*s)", low=0.0, high=1.0e6,
                      description="integral gain (per second; Table 4's 0.1 per sample at T = 10 ms is 10)")
    integral_limit: float = param(127.0, unit="drive", low=0.0, high=1.0e12,
                                  description="clamp of the integral term (anti-windup)")

    def __post_init__(self) -> None:
        for name in ("e_centres", "de_centres", "u_centres"):
            object.__setattr__(self, name, _check_centres(name, getattr(self, name)))
        object.__setattr__(self, "rule_base", _check_rule_base(self.rule_base))
        check_ranges(self, "fuzzy")

    def output_table(self) -> tuple[tuple[float, ...], ...]:
        """Return the 7x7 output centres C_ij (DAC, before ``u_scale``) of the rule base."""
        index = {name: k for k, name in enumerate(SET_NAMES)}
        rows: RuleBase = self.rule_base  # type: ignore[assignment]  # normalised in __post_init__
        return tuple(tuple(self.u_centres[index[name]] for name in row) for row in rows)


def _inverse_widths(centres: Sequence[float]) -> tuple[float, ...]:
    return tuple(1.0 / (centres[k + 1] - centres[k]) for k in range(N_SETS - 1))


def memberships(x: float, centres: Sequence[float]) -> tuple[float, ...]:
    """Return the degrees of membership of ``x`` in the seven sets (reference code, slow).

    Parameters
    ----------
    x : float
        Input, in the unit of ``centres``.
    centres : sequence of 7 float
        Strictly increasing set centres.

    Returns
    -------
    tuple of 7 float
        Triangles with feet at the neighbours' centres, shoulders below the
        first and above the last centre. They sum to 1 for every finite ``x``.
    """
    degrees = []
    for k, c in enumerate(centres):
        if x <= c:
            left = centres[k - 1] if k > 0 else None
            degrees.append(1.0 if left is None else max(0.0, (x - left) / (c - left)))
        else:
            right = centres[k + 1] if k < N_SETS - 1 else None
            degrees.append(1.0 if right is None else max(0.0, (right - x) / (right - c)))
    return tuple(degrees)


def _locate(
    x: float, centres: Sequence[float], inverse_widths: Sequence[float]
) -> tuple[int, float]:
    """Return ``(i, m)``: ``x`` is in set ``i + 1`` to degree ``m``, in set ``i`` to ``1 - m``."""
    i = bisect_right(centres, x) - 1
    if i < 0:
        return 0, 0.0
    if i > N_SETS - 2:
        return N_SETS - 2, 1.0
    return i, (x - centres[i]) * inverse_widths[i]


def _infer(cell: tuple[float, float, float, float], a: float, b: float) -> float:
    """Eq. 8 over the four rules of ``cell`` (outputs c00, c01, c10, c11), Mamdani min weights.

    ``a`` is the degree of the upper error set, ``b`` that of the upper de set.
    """
    weights = (min(1.0 - a, 1.0 - b), min(1.0 - a, b), min(a, 1.0 - b), min(a, b))
    # The largest weight is >= 0.5 (the min of the two larger degrees), so never 0/0.
    return sum(w * c for w, c in zip(weights, cell)) / sum(weights)


class FuzzySurface:
    """The PD part ``u_scale * F[e_scale * e, de_scale * de]`` of the FLC, in DAC.

    This is the readable reference of the map; :meth:`FuzzyLaw.step` inlines
    the same arithmetic for speed (the tests check that they agree). The
    scales are folded into the tables: the input centres are divided by the
    input scales and the output centres multiplied by ``u_scale``. Inputs
    beyond the outermost centres saturate (shoulders), so every output lies in
    ``u_scale * [min(u_centres), max(u_centres)]``.

    Attributes
    ----------
    e_points : tuple of 7 float
        Error centres in counts of unscaled error (``e_centres / e_scale``).
    de_points : tuple of 7 float
        Error-rate centres in counts/s (``de_centres / de_scale``).
    cells : 6x6 tuple of 4-tuples of float
        Output centres (DAC, times ``u_scale``) of the rules of each cell:
        ``cells[i][j] = (C[i][j], C[i][j+1], C[i+1][j], C[i+1][j+1])``.
    """

    def __init__(self, config: FuzzyConfig) -> None:
        self.e_points = tuple(c / config.e_scale for c in config.e_centres)
        self.de_points = tuple(c / config.de_scale for c in config.de_centres)
        self.e_inverse_widths = _inverse_widths(self.e_points)
        self.de_inverse_widths = _inverse_widths(self.de_points)
        t = [[config.u_scale * c for c in row] for row in config.output_table()]
        self.cells = tuple(
            tuple((t[i][j], t[i][j + 1], t[i + 1][j], t[i + 1][j + 1]) for j in range(N_SETS - 1))
            for i in range(N_SETS - 1)
        )

    def __call__(self, e: float, de: float) -> float:
        """Return the PD part (drive units) for the error ``e`` [counts] and its rate ``de`` [counts/s]."""
        i, a = _locate(e, self.e_points, self.e_inverse_widths)
        j, b = _locate(de, self.de_points, self.de_inverse_widths)
        return _infer(self.cells[i][j], a, b)


class FuzzyLaw:
    """The FLC servo law ``u = u_scale * F[e_scale * e, de_scale * de] + u_I`` (paper 000, Eq. 3).

    ``step`` returns the feedback command in DAC, unsaturated; the servo
    controller adds the feedforward, saturates and quantises it.
    """

    def __init__(self, config: FuzzyConfig) -> None:
        self.output = LawOutput()
        self._prev_error = 0.0
        self._integral = 0.0
        self.retune(config)

    def retune(self, config: FuzzyConfig) -> None:
        """Swap the map, ``ki`` and the clamp, keeping e(k-1) and u_I (the integral is clamped anew)."""
        self.config = require_config("fuzzy", config, FuzzyConfig)
        self.surface = FuzzySurface(config)
        s = self.surface
        self._e_c, self._de_c, self._cells = s.e_points, s.de_points, s.cells
        self._e_inv, self._de_inv = s.e_inverse_widths, s.de_inverse_widths
        self._ki = config.ki
        self._limit = limit = config.integral_limit
        self._integral = max(-limit, min(limit, self._integral))

    @property
    def integral(self) -> float:
        """The integral term u_I(k) of the last step, DAC."""
        return self._integral

    def reset(self) -> None:
        """Forget the past: e(k-1) = 0 and u_I = 0 (as the incremental PID of Eq. 14)."""
        self._prev_error = 0.0
        self._integral = 0.0

    def step(self, sample: LawSample) -> LawOutput:
        """The command (drive units) for ``sample.error_counts`` over ``sample.dt_s``.

        The body is :class:`FuzzySurface` inlined: this runs every sample of
        every axis, and a function call costs a fifth of the step.

        Raises
        ------
        FaultError
            If the error is NaN or infinite (the state is left unchanged).
        """
        error, dt_s = sample.error_counts, sample.dt_s
        if error - error != 0.0:  # NaN or +-inf, cheaper than math.isfinite
            raise FaultError(f"fuzzy law: error must be finite, got {error!r}")
        de = (error - self._prev_error) / dt_s
        self._prev_error = error
        integral = self._integral + self._ki * dt_s * error
        limit = self._limit
        integral = limit if integral > limit else (-limit if integral < -limit else integral)
        self._integral = integral
        c = self._e_c
        i = bisect_right(c, error) - 1
        if i < 0:
            i, a = 0, 0.0
        elif i > 5:  # N_SETS - 2, the last cell
            i, a = 5, 1.0
        else:
            a = (error - c[i]) * self._e_inv[i]
        c = self._de_c
        j = bisect_right(c, de) - 1
        if j < 0:
            j, b = 0, 0.0
        elif j > 5:
            j, b = 5, 1.0
        else:
            b = (de - c[j]) * self._de_inv[j]
        c00, c01, c10, c11 = self._cells[i][j]
        a0 = 1.0 - a
        b0 = 1.0 - b
        w00 = a0 if a0 < b0 else b0
        w01 = a0 if a0 < b else b
        w10 = a if a < b0 else b0
        w11 = a if a < b else b
        out = self.output
        out.feedback = (w00 * c00 + w01 * c01 + w10 * c10 + w11 * c11) / (w00 + w01 + w10 + w11) + integral
        return out

