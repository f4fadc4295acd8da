"""Programs of the blending bench: what CAM emits.

Polygon circles, acute stars, pockets of short moves, arc chains (tangent, and with line-arc and
arc-arc corners), rasters, a zig-zag of 150° turns (where a blend can be slower than a stop) and 3-axis
ramps between arcs.

All at ``FEED_M_S`` (1300 mm/min); sizes in m.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cnc_contour_control.motion.geometry import ArcSegment, LineSegment, Program, Segment

FEED_M_S = 1300.0 / 60000.0


def _xy(x_m: float, y_m: float) -> np.ndarray:
    """A point of the xy plane, m."""
    return np.array([x_m, y_m])
CIRCLE_RADIUS_M = 0.02


def polyline(name: str, points_m: np.ndarray, axes: tuple[str, ...] = ("x", "y")) -> Program:
    """Lines through ``points_m`` (shape ``(N, n_axes)``, m) at ``FEED_M_S``."""
    return Program(name, axes, tuple(LineSegment(points_m[i], points_m[i + 1], FEED_M_S)
                                     for i in range(len(points_m) - 1)))


def polygon(sides: int, radius_m: float = CIRCLE_RADIUS_M) -> Program:
    """A closed regular polygon inscribed in the circle of ``radius_m`` around the origin, from (R, 0), CCW."""
    angles = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    points = np.c_[radius_m * np.cos(angles), radius_m * np.sin(angles)]
    points[-1] = points[0]
    return polyline(f"circle-{sides}-gon", points)


def true_circle(radius_m: float = CIRCLE_RADIUS_M) -> Program:
    """The full circle the polygons approximate, as one arc."""
    start = _xy(radius_m, 0.0)
    return Program("circle-arc", ("x", "y"), (ArcSegment(start, start, _xy(0.0, 0.0), False, (0, 1), FEED_M_S),))


def star(tips: int = 5, outer_m: float = 0.02, inner_m: float = 0.006) -> Program:
    """A star with ``tips`` acute tips (36° at 5 tips with these radii)."""
    angles = np.linspace(0.0, 2.0 * math.pi, 2 * tips + 1)
    radii = np.where(np.arange(2 * tips + 1) % 2 == 0, outer_m, inner_m)
    points = np.c_[radii * np.cos(angles), radii * np.sin(angles)]
    points[-1] = points[0]
    return polyline(f"star-{tips}", points)


def pocket(chord_m: float = 2e-4, inner_m: float = 0.001, outer_m: float = 0.015, pitch_m: float = 8e-4) -> Program:
    """A spiral pocket as CAM writes it: an Archimedean spiral in chords of ``chord_m``, then a square finish."""
    turns = (outer_m - inner_m) / pitch_m
    theta, points = 0.0, []
    while theta <= 2.0 * math.pi * turns:
        radius = inner_m + pitch_m * theta / (2.0 * math.pi)
        points.append((radius * math.cos(theta), radius * math.sin(theta)))
        theta += chord_m / radius
    end = np.array(points[-1])
    square = [end + [0.0, -outer_m], end + [-2 * outer_m, -outer_m], end + [-2 * outer_m, outer_m],
              end + [0.0, outer_m]]
    return polyline("pocket", np.vstack([np.array(points), square]))


def arc_chain(radii_m: tuple[float, ...] = (5e-4, 1e-3, 2e-3, 4e-3), repeats: int = 6) -> Program:
    """Semicircles of the given radii, alternating G2/G3, tangent at every junction (an S-chain along x)."""
    segments: list[Segment] = []
    x = 0.0
    for i in range(repeats * len(radii_m)):
        radius = radii_m[i % len(radii_m)]
        segments.append(ArcSegment(_xy(x, 0.0), _xy(x + 2 * radius, 0.0), _xy(x + radius, 0.0), i % 2 == 0, (0, 1),
                                   FEED_M_S))
        x += 2 * radius
    return Program("arc-chain", ("x", "y"), tuple(segments))


def arc_scallops(radii_m: tuple[float, ...] = (5e-4, 1e-3, 2e-3, 4e-3), repeats: int = 6,
                 sweep_rad: float = math.pi / 2) -> Program:
    """Clockwise 90° arcs of the given radii along x, each bulging up: a 90° arc-arc corner at every junction."""
    segments: list[Segment] = []
    x = 0.0
    for i in range(repeats * len(radii_m)):
        radius = radii_m[i % len(radii_m)]
        chord = 2.0 * radius * math.sin(0.5 * sweep_rad)
        center = _xy(x + 0.5 * chord, -radius * math.cos(0.5 * sweep_rad))
        segments.append(ArcSegment(_xy(x, 0.0), _xy(x + chord, 0.0), center, True, (0, 1), FEED_M_S))
        x += chord
    return Program("arc-scallops", ("x", "y"), tuple(segments))


def lines_and_arcs(radii_m: tuple[float, ...] = (5e-4, 1e-3, 2e-3, 4e-3), repeats: int = 3,
                   line_m: float = 3e-3) -> Program:
    """Lines alternating with 120° arcs of the given radii: 60° line-arc and arc-line corners."""
    segments: list[Segment] = []
    x = 0.0
    for i in range(repeats * len(radii_m)):
        radius = radii_m[i % len(radii_m)]
        segments.append(LineSegment(_xy(x, 0.0), _xy(x + line_m, 0.0), FEED_M_S))
        x += line_m
        chord = 2.0 * radius * math.sin(math.pi / 3.0)
        segments.append(ArcSegment(_xy(x, 0.0), _xy(x + chord, 0.0), _xy(x + 0.5 * chord, -0.5 * radius), True, (0, 1),
                                   FEED_M_S))
        x += chord
    return Program("lines-and-arcs", ("x", "y"), tuple(segments))


def raster(passes: int = 10, step_m: float = 5e-4, width_m: float = 0.04, stepover_m: float = 0.002) -> Program:
    """A 3-axis surface raster: passes along x over z = 2 mm sin(x / 8 mm) cos(y / 10 mm), stepovers in y and z."""
    x = np.arange(0.0, width_m + step_m / 2, step_m)
    rows = []
    for i in range(passes):
        y = i * stepover_m
        xs = x if i % 2 == 0 else x[::-1]
        rows.append(np.c_[xs, np.full_like(xs, y), 0.002 * np.sin(xs / 0.008) * np.cos(y / 0.01)])
    return polyline("raster-3axis", np.vstack(rows), ("x", "y", "z"))


def zigzag(turn_deg: float = 150.0, segments: int = 30, length_m: float = 0.005) -> Program:
    """Lines of ``length_m`` along x, alternately up and down, turning by ``turn_deg`` at every junction."""
    half = math.radians(0.5 * turn_deg)
    steps = np.array([[math.cos(half), math.sin(half) * (1 if i % 2 == 0 else -1)] for i in range(segments)])
    points = np.vstack([np.zeros(2), np.cumsum(length_m * steps, axis=0)])
    return polyline(f"zigzag-{turn_deg:g}", points)


def ramps_3axis(repeats: int = 6, radius_m: float = 0.003, ramp_m: tuple[float, float, float] = (0.004, 0.002, -5e-4)
                ) -> Program:
    """Quarter arcs in xy (CCW, z constant) joined by ramps moving x, y and z at once: 3-axis line-arc corners."""
    segments: list[Segment] = []
    point = np.zeros(3)
    for _ in range(repeats):
        end = point + np.asarray(ramp_m)
        segments.append(LineSegment(point, end, FEED_M_S))
        center = end + np.array([0.0, radius_m, 0.0])
        arc_end = center + np.array([radius_m, 0.0, 0.0])
        segments.append(ArcSegment(end, arc_end, center, False, (0, 1), FEED_M_S))
        point = arc_end
    return Program("ramps-3axis", ("x", "y", "z"), tuple(segments))


#: Program name -> generator, in the bench's order. ``quick`` leaves out those marked False.
CORPUS: dict[str, tuple[Callable[[], Program], bool]] = {
    "circle-36-gon": (lambda: polygon(36), True),
    "circle-360-gon": (lambda: polygon(360), True),
    "circle-3600-gon": (lambda: polygon(3600), False),
    "star-5": (star, True),
    "pocket": (pocket, True),
    "arc-chain": (arc_chain, True),
    "arc-scallops": (arc_scallops, True),
    "lines-and-arcs": (lines_and_arcs, True),
    "raster-3axis": (raster, True),
    "zigzag-150": (zigzag, True),
    "ramps-3axis": (ramps_3axis, True),
}
