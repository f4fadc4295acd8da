"""The reference's own deviation from the programmed path, beside the path tolerance it was planned with.

With a path tolerance (G64 P, ``interpolator.path_tolerance_mm``) the
interpolator rounds corners: its reference leaves the programmed path by up to
the tolerance. The contour error (scoring) measures the machine against the
programmed path, so it holds that deviation too; this part of the score
tells them apart: the exact distance of every reference sample from the
programmed path (``Program.contour_distance``), its largest value and RMS
(``metrics`` ``max`` and ``rms``), and the tolerance the record carries
(``RunRecord.program.path_tolerance_m``: the tolerance the interpolator
planned with, the program's G64 P / G61 or else its ``path_tolerance_mm``, as
the engine records it and as a bag's ``Path`` message carries it; None when the
record does not say: a bag recorded before ``Path`` had the field, or a NaN
there). A deviation over the tolerance (beyond 1 nm of rounding) is a verdict
line of the score.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cnc_contour_control.core.units import M_PER_UM
from cnc_tools.analysis.metrics import evaluate, get_metrics, trapezoid_weights_s
from cnc_tools.run_record import RunRecord

#: Metrics of the deviation (from the registry).
DEVIATION_METRICS: tuple[str, ...] = ("max", "rms")
#: Rounding allowed over the tolerance, m (an exact-stop reference is on the path to ~1e-17 m).
ROUNDING_M = 1.0e-9


@dataclass(frozen=True)
class ReferenceDeviation:
    """Distance of the reference from the programmed path over ``n_samples`` samples.

    ``values_si`` holds the metrics (m) by name; ``tolerance_m`` is the path tolerance (m) the run was
    planned with, or None when the record does not carry it.
    """

    n_samples: int
    values_si: Mapping[str, float]
    tolerance_m: float | None

    @property
    def max_m(self) -> float:
        """Largest deviation, m (NaN without samples)."""
        return self.values_si["max"]

    @property
    def exceeded(self) -> bool:
        """True when the largest deviation is over the tolerance by more than ``ROUNDING_M``."""
        return self.tolerance_m is not None and self.max_m > self.tolerance_m + ROUNDING_M

    def verdict(self) -> str | None:
        """The verdict line when the tolerance is exceeded, else None."""
        if not self.exceeded:
            return None
        return (f"the reference deviates {self.max_m / M_PER_UM:.4g} µm from the programmed path, over its path "
                f"tolerance {_tolerance_text(self.tolerance_m)}")

    def to_dict(self) -> dict[str, object]:
        """Plain data in µm (keys carry the unit)."""
        return {"n_samples": self.n_samples,
                **{f"{name}_um": value / M_PER_UM for name, value in self.values_si.items()},
                "tolerance_um": None if self.tolerance_m is None else self.tolerance_m / M_PER_UM,
                "exceeded": self.exceeded, "verdict": self.verdict()}

    def lines(self) -> list[str]:
        """Lines for the score's table."""
        figures = ", ".join(f"{name} {_fmt(value / M_PER_UM)} µm" for name, value in self.values_si.items())
        out = [f"reference deviation from the programmed path (blends): {figures} over {self.n_samples} samples; "
               f"path tolerance {_tolerance_text(self.tolerance_m)}"]
        verdict = self.verdict()
        return out + ([f"verdict: {verdict}"] if verdict else [])


def _fmt(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.5g}"


def _tolerance_text(tolerance_m: float | None) -> str:
    if tolerance_m is None:
        return "not recorded"
    return "0 (exact stop)" if tolerance_m == 0.0 else f"{tolerance_m / M_PER_UM:.5g} µm"


def reference_deviation(run: RunRecord) -> ReferenceDeviation | None:
    """The deviation of ``run``'s reference (finite samples) from its program; None without a reference."""
    if run.reference is None:
        return None
    finite = np.isfinite(run.reference.position_m).all(axis=1)
    points, stamps = run.reference.position_m[finite], run.reference.stamp_ns[finite]
    distance = run.program.contour_distance(points)[0] if points.size else np.zeros(0)
    values = evaluate(get_metrics(DEVIATION_METRICS), distance, trapezoid_weights_s(stamps * np.float64(1e-9)))
    return ReferenceDeviation(int(distance.size), values, run.program.path_tolerance_m)
