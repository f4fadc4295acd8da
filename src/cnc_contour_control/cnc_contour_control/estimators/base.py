"""The seam of the contour-error estimators: one estimate per tick, the protocol, the sign convention.

Sign convention (fixed by ``ContourError.msg``; the compensators rely on it)::

    θ    = atan2(t_b, t_a)             direction of travel of the local contour tangent t in the plane (a, b)
    n    = (−sin θ, cos θ)             left normal of the direction of travel
    ε_c  = (P − P_line) · n            > 0 when the actual position P lies LEFT of the direction of travel

with ``P_line`` a point of the local contour line (the nearer stored reference
point for the window estimator, the nearest programmed point for the path
estimator). So ``∂ε_c/∂c = n = (−sin θ, cos θ)`` for the axis positions
``c = (c_a, c_b)``: a compensator's learning law must take these signs.

Relation to paper 001, Eq. 2, ``ε_c = sign(x2 − x1)·(−e'_x sin θ + e'_y cos θ)``
with ``θ = atan((y2 − y1)/(x2 − x1))``: ``atan`` knows the line's direction
only up to π, and the factor ``sign(x2 − x1)`` restores the orientation. With
``atan2`` of the direction of travel the factor is not needed and Eq. 2
becomes ``ε_c = −e'_x sin θ + e'_y cos θ`` with ``e' = P − P2*``: ours. The
paper leaves two things open that each flip the sign: which of the pair is
the later stored point (its steps 5–6 make P1* the later one, so
``x2 − x1`` points against the travel) and whether ``e'`` is position minus
reference or the reverse. With P1* the later point and ``e' = P − P2*`` Eq. 2
is positive to the RIGHT of travel, i.e. ``−ε_c`` here; its stated
derivatives ``∂ε_c/∂c = (sin θ, −cos θ)`` are that right normal. We use the
left-positive form of ``ContourError.msg`` throughout.

Three or more axes: the magnitude is the distance in space (to the line or
to the segment); the sign is that of the offset's component along the left
normal of the tangent's projection on the contour plane (config ``plane``,
two axis indices; a helix around z has the plane XY, ``(0, 1)``). A zero
component (or a tangent with no projection on the plane) counts as positive.
``angle_rad`` is θ of that projection.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

from cnc_contour_control.core.errors import ConfigError, FaultError
from cnc_contour_control.core.slots import SlotsRecord

__all__ = ["ContourEstimate", "ContourEstimator", "check_plane", "check_sample"]


class ContourEstimate(SlotsRecord):
    """One tick's estimate; built every tick, so a plain slots class (read-only by convention).

    Attributes
    ----------
    contour_error_m : float
        Signed contour error, m (> 0 left of travel; see the module docstring).
    tracking_error_m : tuple of float
        Reference − position per axis, m, in axis order.
    angle_rad : float
        Direction of travel of the local contour tangent in the contour plane, rad (atan2).
    segment_index : int
        Window estimator: stored reference index of the nearer point P2* (0 = the
        run's first stored reference). Path estimator: the program segment.
    point_a_m, point_b_m : tuple of float
        The two points the estimate used, m. Window estimator: P1* (the second
        nearest stored point) and P2* (the nearest). Path estimator: the nearest
        point on the segment and that segment's start.
    window_size : int
        Window estimator: stored reference points whose distance was computed this
        sample. Path estimator: segments whose nearest point was computed.
    steps : int
        Index moves walked this sample (stored points, or segments).
    """

    __slots__ = ("contour_error_m", "tracking_error_m", "angle_rad", "segment_index", "point_a_m", "point_b_m",
                 "window_size", "steps")

    def __init__(self, contour_error_m: float, tracking_error_m: tuple[float, ...], angle_rad: float,
                 segment_index: int, point_a_m: tuple[float, ...], point_b_m: tuple[float, ...],
                 window_size: int, steps: int) -> None:
        self.contour_error_m = contour_error_m
        self.tracking_error_m = tracking_error_m
        self.angle_rad = angle_rad
        self.segment_index = segment_index
        self.point_a_m = point_a_m
        self.point_b_m = point_b_m
        self.window_size = window_size
        self.steps = steps


class ContourEstimator(Protocol):
    """What every estimator keeps: ``reset`` and one ``step`` per tick."""

    def reset(self) -> None:
        """Forget every stored sample (a new run)."""

    def step(self, ref_position_m: Sequence[float], position_m: Sequence[float]) -> ContourEstimate:
        """This tick's reference and measured position (axis order, m) to an estimate.

        A non-finite input raises :class:`FaultError` naming the input and the
        axis; the estimator's state is untouched then.
        """


def check_plane(plane: Any, axis_count: int | None = None, context: str = "estimator") -> tuple[int, int]:
    """``plane`` as two distinct axis indices (within ``axis_count`` when given); ConfigError otherwise."""
    try:
        a, b = (int(i) for i in plane)
        valid = all(float(i) == int(i) and not isinstance(i, bool) for i in plane)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{context}.plane must be two axis indices, got {plane!r}") from err
    high = (axis_count - 1) if axis_count is not None else None
    if not valid or a == b or a < 0 or b < 0 or (high is not None and max(a, b) > high):
        bound = f" in [0, {high}]" if high is not None else " >= 0"
        raise ConfigError(f"{context}.plane must be two distinct axis indices{bound}, got {plane!r}")
    return a, b


def check_sample(ref_position_m: Sequence[float], position_m: Sequence[float], axis_count: int,
                 axis_names: Sequence[str] | None = None) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Both inputs as float tuples of ``axis_count`` finite entries; FaultError naming input and axis otherwise."""
    if len(ref_position_m) != axis_count or len(position_m) != axis_count:
        raise FaultError(f"estimator: ref_position_m and position_m must have {axis_count} entries (one per axis), "
                         f"got {len(ref_position_m)} and {len(position_m)}")
    ref, pos = tuple(map(float, ref_position_m)), tuple(map(float, position_m))
    checksum = sum(ref) + sum(pos)
    if checksum - checksum != 0.0:  # a NaN or an infinity among the inputs (or an overflow)
        for name, values in (("ref_position_m", ref), ("position_m", pos)):
            for axis, value in enumerate(values):
                if not math.isfinite(value):
                    label = f" ({axis_names[axis]})" if axis_names else ""
                    raise FaultError(f"estimator: {name}[{axis}]{label} must be finite, got {value!r}")
    return ref, pos
