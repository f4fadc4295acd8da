"""Paper 001's contour-error model: the variable-window search over the stored reference points (Section 2.1).

One sample (``k`` the index of the nearest stored point found last time)::

    store P*(t)                      in a ring memory of memory_points, unless within min_spacing_m of the last stored
    walk k forward while ‖P*(k+1) − P‖ < ‖P*(k) − P‖       (steps 1–3, in the direction the distance falls;
    else walk k backward while ‖P*(k−1) − P‖ < ‖P*(k) − P‖   the paper walks from k+1 backward only)
    P2* = P*(k); P1* = the nearer of P*(k−1), P*(k+1)      (steps 4–6)
    ε_c = signed distance from P to the line through P1*, P2*   (Eq. 2 with atan2; sign in :mod:`.base`)
    ahead: P2* the newest point and P past it along the last chord  →  ε_c = signed distance from P to the
           circle through the three newest stored points, continued past P2* (:func:`ahead_error`)

Ahead of the reference (paper 001's own loop leads in about three moving
samples of four) no stored point lies beyond the position, and the last
chord's extension leaves an arc of radius ρ by about d²/2ρ after a lead d
(20 µm at 0.6 mm on r = 10 mm). The circle through the three newest points is
the arc itself on an arc and the line on a line, so the estimate stays exact
on both while the program goes on; past an open program's end (or an exact
stop's vertex) the exact error is the distance to that point, which no
estimator built on past references sees.

In steady state the nearest point advances one stored point per sample, so a
sample walks one step and computes about four distances, whatever the
program's length; the memory is a ring of ``memory_points`` points. Stored
indices count from 0 at the run's first stored reference; a nearest index
that has fallen out of the ring restarts at the oldest point kept.

Before two distinct reference points are stored (the first tick, and while
the reference stands still at the start) no line exists: the estimate is
``contour_error_m = 0`` and ``angle_rad = 0`` with ``window_size = 1``, P1* =
P2* = the one stored point (the paper's step 0 sets P1* = P2* = P*(0)). At the
start the axes stand on the reference, so the exact error is 0 there too.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from operator import mul, sub

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.params import check_ranges, param
from cnc_contour_control.estimators.base import ContourEstimate, check_plane, check_sample

_dist = math.dist


@dataclass(frozen=True)
class WindowEstimatorConfig:
    """Validated configuration of the window estimator.

    Parameters
    ----------
    memory_points : int
        Capacity of the ring memory of stored reference points, in [3, 1e7]. It
        must cover the following error in samples (lag / T) with margin.
    min_spacing_m : float
        A reference closer than this to the last stored point is not stored
        (the reference standing still), m, in [1e-12, 1e-3].
    max_steps : int
        Most index moves per sample (bounds a sample's cost; the walk goes on
        next sample), in [1, 1e7].
    plane : tuple of int
        Axis indices of the contour plane that fixes the sign and the angle, ``(0, 1)`` = XY.
    """

    memory_points: int = param(4096, unit="points", low=3, high=10_000_000, read_only=True,
                               description="capacity of the ring memory of past reference points")
    min_spacing_m: float = param(1.0e-9, unit="m", low=1.0e-12, high=1.0e-3,
                                 description="a reference closer than this to the last stored one is not stored")
    max_steps: int = param(256, unit="steps", low=1, high=10_000_000,
                           description="most window steps walked per sample")
    plane: tuple[int, int] = param((0, 1), read_only=True,
                                   description="axis indices of the contour plane (sign and angle)")

    def __post_init__(self) -> None:
        for name in ("memory_points", "max_steps"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ConfigError(f"window.{name} must be an integer, got {value!r}")
        check_ranges(self, "window")
        object.__setattr__(self, "plane", check_plane(self.plane, context="window"))


class WindowEstimator:
    """The variable-window estimator over a bounded memory of past references (see the module docstring).

    Parameters
    ----------
    config : WindowEstimatorConfig
        Validated configuration.
    axis_count : int
        Number of axes of every sample; ``config.plane`` must lie within them.
    axis_names : sequence of str, optional
        Names for error messages.
    """

    def __init__(self, config: WindowEstimatorConfig, axis_count: int,
                 axis_names: Sequence[str] | None = None) -> None:
        if isinstance(axis_count, bool) or not isinstance(axis_count, int) or axis_count < 2:
            raise ConfigError(f"window estimator axis_count must be an integer >= 2, got {axis_count!r}")
        self.config = config
        self.axis_count = axis_count
        self.axis_names = tuple(axis_names) if axis_names is not None else None
        self._plane = check_plane(config.plane, axis_count, "window")
        self._line = line_error_2 if axis_count == 2 else line_error
        self._capacity = config.memory_points
        self._memory: list[tuple[float, ...]] = []
        self._count = 0
        self._nearest = 0
        self.reset()

    def reset(self) -> None:
        """Empty the memory (a new run)."""
        self._memory = [()] * self._capacity
        self._count = 0
        self._nearest = 0

    @property
    def stored_count(self) -> int:
        """Reference points stored since the last reset (the ring keeps the last ``memory_points``)."""
        return self._count

    @property
    def memory_size(self) -> int:
        """Points the ring holds now (at most ``memory_points``)."""
        return min(self._count, self._capacity)

    def step(self, ref_position_m: Sequence[float], position_m: Sequence[float]) -> ContourEstimate:
        """Store this tick's reference, then estimate the contour error of ``position_m`` (m, axis order)."""
        ref, pos = check_sample(ref_position_m, position_m, self.axis_count, self.axis_names)
        self._store(ref)
        tracking = tuple(map(sub, ref, pos))
        if self._count == 1:
            only = self._memory[0]
            return ContourEstimate(0.0, tracking, 0.0, 0, only, only, 1, 0)
        nearest, second, window_size, steps = self._search(pos)
        self._nearest = nearest
        memory, capacity = self._memory, self._capacity
        near, other = memory[nearest % capacity], memory[second % capacity]
        earlier, later = (other, near) if second < nearest else (near, other)
        if nearest == self._count - 1 and nearest >= 2:  # the ring holds the two before it (memory_points >= 3)
            ahead = ahead_error(pos, memory[(nearest - 2) % capacity], other, near, self._plane)
            if ahead is not None:
                return ContourEstimate(ahead[0], tracking, ahead[1], nearest, other, near, window_size, steps)
        error, angle = self._line(pos, near, earlier, later, self._plane)
        return ContourEstimate(error, tracking, angle, nearest, other, near, window_size, steps)

    def _store(self, ref: tuple[float, ...]) -> None:
        count = self._count
        if count and _dist(ref, self._memory[(count - 1) % self._capacity]) < self.config.min_spacing_m:
            return
        self._memory[count % self._capacity] = ref
        self._count = count + 1

    def _search(self, pos: tuple[float, ...]) -> tuple[int, int, int, int]:
        """Steps 1–6: (nearest index, second index, distances computed, index moves)."""
        memory, capacity, count, limit = self._memory, self._capacity, self._count, self.config.max_steps
        oldest = max(0, count - capacity)
        k = min(max(self._nearest, oldest), count - 1)
        d_k, d_next, d_prev = _dist(memory[k % capacity], pos), math.inf, math.inf
        evaluated, steps = 1, 0
        while k + 1 < count and steps < limit:
            d = _dist(memory[(k + 1) % capacity], pos)
            evaluated += 1
            if d >= d_k:
                d_next = d
                break
            d_prev, d_k, k, steps = d_k, d, k + 1, steps + 1
        if steps == 0:
            while k > oldest and steps < limit:
                d = _dist(memory[(k - 1) % capacity], pos)
                evaluated += 1
                if d >= d_k:
                    d_prev = d
                    break
                d_next, d_k, k, steps = d_k, d, k - 1, steps + 1
        second = k - 1 if d_prev < d_next else k + 1
        return k, second, evaluated, steps


def line_error(pos: Sequence[float], near: Sequence[float], earlier: Sequence[float], later: Sequence[float],
               plane: tuple[int, int]) -> tuple[float, float]:
    """Signed distance (m) from ``pos`` to the line through ``earlier`` → ``later``, and the travel angle (rad).

    The line passes through ``near`` (one of the two points); travel runs from
    ``earlier`` to ``later`` (distinct points). The magnitude is the distance
    in space; the sign that of the offset's component along the left normal
    of the travel direction projected on ``plane`` (zero counts as positive);
    the angle is ``atan2`` of that projection. Two axes take
    :func:`line_error_2`, the same result in plane arithmetic.
    """
    if len(pos) == 2:
        return line_error_2(pos, near, earlier, later, plane)
    u, e = list(map(sub, later, earlier)), list(map(sub, pos, near))
    along = sum(map(mul, e, u)) / sum(map(mul, u, u))
    distance = math.sqrt(sum([(x - along * y) ** 2 for x, y in zip(e, u)]))
    a, b = plane
    side = u[a] * e[b] - u[b] * e[a]
    return (distance if side >= 0.0 else -distance), math.atan2(u[b], u[a])


def line_error_2(pos: Sequence[float], near: Sequence[float], earlier: Sequence[float], later: Sequence[float],
                 plane: tuple[int, int]) -> tuple[float, float]:
    """:func:`line_error` for two axes: the cross product over the chord length (the per-tick path in 2 axes)."""
    a, b = plane
    ua, ub = later[a] - earlier[a], later[b] - earlier[b]
    side = ua * (pos[b] - near[b]) - ub * (pos[a] - near[a])
    return side / math.hypot(ua, ub) + 0.0, math.atan2(ub, ua)


def ahead_error(pos: Sequence[float], first: Sequence[float], middle: Sequence[float], newest: Sequence[float],
                plane: tuple[int, int]) -> tuple[float, float] | None:
    """Signed distance (m) from ``pos`` to the circle through three stored points, continued past ``newest``.

    None when ``pos`` is not past ``newest`` (its offset from ``newest`` has no
    positive component along the circle's tangent there): the chord line
    then measures it (between the two newest points, or behind them).

    The circle is taken in ``plane`` with signed curvature κ (> 0 turning
    left) through ``first`` → ``middle`` → ``newest``. With ``u``, ``v`` the
    position's offset from ``newest`` along the circle's tangent there and
    its left normal, the signed distance is, without the centre (so a line,
    κ = 0, gives ``v`` and a nearly straight path loses no digits)::

        ε = (2v − κ(u² + v²)) / (1 + √((κu)² + (1 − κv)²))

    Further axes are continued along the arc length at the last chord's
    slope; their offset counts in the distance, not in the sign (as
    :func:`line_error`). The angle is the direction of travel at the circle's
    point nearest ``pos`` (rad, atan2). A chord with no extent in the plane
    falls back to :func:`line_error` through ``middle`` → ``newest``.
    """
    a, b = plane
    ca, cb = newest[a] - middle[a], newest[b] - middle[b]
    pa, pb = middle[a] - first[a], middle[b] - first[b]
    chord, previous = math.hypot(ca, cb), math.hypot(pa, pb)
    span = math.hypot(newest[a] - first[a], newest[b] - first[b])
    if chord * previous * span == 0.0:
        return line_error(pos, newest, middle, newest, plane) if _past(pos, middle, newest) else None
    kappa = 2.0 * (pa * cb - pb * ca) / (chord * previous * span)
    sin_half = max(-1.0, min(1.0, 0.5 * kappa * chord))  # the tangent at newest: the chord turned by half its arc
    cos_half = math.sqrt(1.0 - sin_half * sin_half)
    ta, tb = (ca * cos_half - cb * sin_half) / chord, (cb * cos_half + ca * sin_half) / chord
    da, db = pos[a] - newest[a], pos[b] - newest[b]
    u, v = da * ta + db * tb, db * ta - da * tb
    if u <= 0.0:
        return None
    ku, kv = kappa * u, 1.0 - kappa * v  # (kv, ku) points along the arc turned from newest to the nearest point
    error = (2.0 * v - kappa * (u * u + v * v)) / (1.0 + math.hypot(ku, kv)) + 0.0
    angle = math.atan2(tb * kv + ta * ku, ta * kv - tb * ku)
    if len(pos) == 2:
        return error, angle
    along = math.atan2(ku, kv) / kappa if kappa else u
    return _out_of_plane(error, pos, middle, newest, plane, chord, along), angle


def _past(pos: Sequence[float], middle: Sequence[float], newest: Sequence[float]) -> bool:
    """Whether ``pos`` lies past ``newest`` along the chord ``middle`` → ``newest`` (in space)."""
    return sum(map(mul, map(sub, pos, newest), map(sub, newest, middle))) > 0.0


def _out_of_plane(error: float, pos: Sequence[float], middle: Sequence[float], newest: Sequence[float],
                  plane: tuple[int, int], chord: float, along: float) -> float:
    """``error`` with the other axes' offsets from the continued path (slope of the last chord) in the distance.

    The offset ``w`` at ``along`` (m of in-plane arc past ``newest``) counts by its part normal to the path,
    ``w / √(1 + slope²)``; the sign stays ``error``'s.
    """
    squares, slope2 = 0.0, 0.0
    for axis, (p, m, n) in enumerate(zip(pos, middle, newest)):
        if axis not in plane:
            slope = (n - m) / chord
            squares += (p - n - slope * along) ** 2
            slope2 += slope * slope
    return math.copysign(math.sqrt(error * error + squares / (1.0 + slope2)), error)
