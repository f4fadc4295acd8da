"""Part programs from a scenario's ``program:`` section (mm and mm/min, for people).

Exactly one source key chooses the form (registry :data:`SOURCES`):

``segments``
    explicit contour: ``{axes: [x, y], start_mm: [0, 0], feed_mm_min: 400,
    segments: [{line: {to_mm: [..], feed_mm_min: ..}}, {arc: {to_mm: [..],
    center_mm: [..], direction: cw|ccw, plane: xy}}]}``; a segment's
    ``feed_mm_min`` defaults to the program's. A plane of two of x, y, z
    is oriented as G17/G18/G19 whatever the order (``plane: xz`` + ``ccw``
    turns as G18 G3; see ``docs/gcode.md``).
``shape``
    a generated contour from :data:`SHAPES`: ``line``, ``circle``, ``corner``
    (see their option classes). Shapes lie in the first two axes.
``gcode`` / ``gcode_file``
    G-code text or a file (relative to ``base_dir``), read by
    :func:`~cnc_contour_control.motion.gcode.parse_gcode`; options ``axes``,
    ``rapid_feed_mm_min``, ``start_mm``, ``work_offsets_mm`` (``{G54: [..], ..}``).

A ``name`` key overrides the program name. Unknown keys are a
:class:`~cnc_contour_control.core.errors.ConfigError` listing the valid ones.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.config import (
    build_config,
    require_choice,
    require_range,
)
from cnc_contour_control.core.errors import ConfigError, ProgramError
from cnc_contour_control.core.units import mm_min_to_m_s, mm_to_m
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.gcode_file import read_gcode_file
from cnc_contour_control.motion.geometry import ArcSegment, FloatArray, LineSegment, Program, Segment
from cnc_contour_control.motion.points import require_extent_mm, require_feed_mm_min

#: Arc direction name -> clockwise.
DIRECTIONS: dict[str, bool] = {"cw": True, "ccw": False}


def _axes(value: Any, context: str) -> tuple[str, ...]:
    names = (value,) if isinstance(value, str) else tuple(value) if isinstance(value, (list, tuple)) else ()
    if not names or not all(isinstance(n, str) and n for n in names) or len(set(names)) != len(names):
        raise ConfigError(f"{context}.axes must be distinct non-empty axis names, got {value!r}")
    return names


def _point_mm(name: str, value: Any, n_axes: int, context: str) -> FloatArray:
    """A point in mm as an array of shape ``(n_axes,)``; ``None`` is the origin."""
    if value is None:
        return np.zeros(n_axes)
    values: list[Any] = [value] if np.isscalar(value) else list(value)
    if len(values) != n_axes:
        raise ConfigError(f"{context}.{name} must have {n_axes} entries (one per axis), got {value!r}")
    return np.array([require_extent_mm(f"{name}[{j}]", v, context) for j, v in enumerate(values)])


def _planar_offset_mm(n_axes: int, distance_mm: float, angle_deg: float) -> FloatArray:
    """A vector of ``distance_mm`` at ``angle_deg`` in the plane of the first two axes."""
    offset = np.zeros(n_axes)
    offset[0] = distance_mm * math.cos(math.radians(angle_deg))
    offset[1] = distance_mm * math.sin(math.radians(angle_deg))
    return np.round(offset, 12)  # exact zeros at multiples of 90 degrees


@dataclass(frozen=True)
class LineShape:
    """A straight line of ``length_mm`` at ``angle_deg`` from the first axis (paper 000: 5°)."""

    length_mm: float
    feed_mm_min: float
    angle_deg: float = 0.0
    start_mm: Any = None
    axes: Any = ("x", "y")

    def __post_init__(self) -> None:
        require_extent_mm("length_mm", self.length_mm, "program", positive=True)
        require_feed_mm_min("feed_mm_min", self.feed_mm_min, "program")
        require_range("angle_deg", self.angle_deg, -360.0, 360.0, "program")

    def segments(self, start_mm: FloatArray) -> list[Segment]:
        end_mm = start_mm + _planar_offset_mm(start_mm.size, self.length_mm, self.angle_deg)
        return [LineSegment(mm_to_m(start_mm), mm_to_m(end_mm), mm_min_to_m_s(self.feed_mm_min))]


@dataclass(frozen=True)
class CircleShape:
    """A full circle through ``start_mm``; the start is at ``start_angle_deg`` seen from the centre.

    The default ``start_angle_deg = -90`` puts the centre at ``(0, radius)``
    for a start at the origin, as paper 000's circular test. ``feed_in_deg`` and
    ``feed_out_deg`` (in [0, 360]) add a feed-in arc before the full turn and a
    feed-out arc after it on the same circle, as a ballbar test runs it (the
    measured turn then starts ``feed_in_deg`` after ``start_mm``; see
    docs/circular_test.md).
    """

    radius_mm: float
    feed_mm_min: float
    direction: str = "ccw"
    start_angle_deg: float = -90.0
    start_mm: Any = None
    axes: Any = ("x", "y")
    feed_in_deg: float = 0.0
    feed_out_deg: float = 0.0

    def __post_init__(self) -> None:
        require_extent_mm("radius_mm", self.radius_mm, "program", positive=True)
        require_feed_mm_min("feed_mm_min", self.feed_mm_min, "program")
        require_choice("direction", self.direction, DIRECTIONS, "program")
        require_range("start_angle_deg", self.start_angle_deg, -360.0, 360.0, "program")
        require_range("feed_in_deg", self.feed_in_deg, 0.0, 360.0, "program")
        require_range("feed_out_deg", self.feed_out_deg, 0.0, 360.0, "program")

    def segments(self, start_mm: FloatArray) -> list[Segment]:
        center_mm = start_mm - _planar_offset_mm(start_mm.size, self.radius_mm, self.start_angle_deg)
        turn = 1.0 if self.direction == "ccw" else -1.0

        def point_mm(after_deg: float) -> FloatArray:
            """The point ``after_deg`` along the direction from the start (the start itself at 0 or 360)."""
            if after_deg % 360.0 == 0.0:
                return start_mm
            return center_mm + _planar_offset_mm(start_mm.size, self.radius_mm,
                                                 self.start_angle_deg + turn * after_deg)

        turn_mm = point_mm(self.feed_in_deg)
        arcs = [(start_mm, turn_mm, self.feed_in_deg), (turn_mm, turn_mm, 360.0),
                (turn_mm, point_mm(self.feed_in_deg + self.feed_out_deg), self.feed_out_deg)]
        return [ArcSegment(mm_to_m(a), mm_to_m(b), mm_to_m(center_mm), DIRECTIONS[self.direction], (0, 1),
                           mm_min_to_m_s(self.feed_mm_min)) for a, b, sweep_deg in arcs if sweep_deg > 0.0]


@dataclass(frozen=True)
class CornerShape:
    """Two legs of ``leg_mm``: the first along ``heading_deg``, then a turn of ``angle_deg`` (ccw > 0)."""

    leg_mm: float
    feed_mm_min: float
    angle_deg: float = 90.0
    heading_deg: float = 0.0
    start_mm: Any = None
    axes: Any = ("x", "y")

    def __post_init__(self) -> None:
        require_extent_mm("leg_mm", self.leg_mm, "program", positive=True)
        require_feed_mm_min("feed_mm_min", self.feed_mm_min, "program")
        require_range("angle_deg", self.angle_deg, -180.0, 180.0, "program")
        require_range("heading_deg", self.heading_deg, -360.0, 360.0, "program")

    def segments(self, start_mm: FloatArray) -> list[Segment]:
        corner_mm = start_mm + _planar_offset_mm(start_mm.size, self.leg_mm, self.heading_deg)
        end_mm = corner_mm + _planar_offset_mm(start_mm.size, self.leg_mm, self.heading_deg + self.angle_deg)
        feed_m_s = mm_min_to_m_s(self.feed_mm_min)
        return [LineSegment(mm_to_m(start_mm), mm_to_m(corner_mm), feed_m_s),
                LineSegment(mm_to_m(corner_mm), mm_to_m(end_mm), feed_m_s)]


#: Shape name -> option class (a frozen dataclass with ``segments(start_mm)``).
SHAPES: dict[str, type[LineShape] | type[CircleShape] | type[CornerShape]] = {
    "line": LineShape, "circle": CircleShape, "corner": CornerShape}


@dataclass(frozen=True)
class LineSpec:
    """An explicit line to ``to_mm`` (absolute, mm)."""

    to_mm: Any
    feed_mm_min: float | None = None


@dataclass(frozen=True)
class ArcSpec:
    """An explicit arc to ``to_mm`` around ``center_mm`` (absolute, mm) in ``plane`` (e.g. ``xy``)."""

    to_mm: Any
    center_mm: Any
    direction: str
    plane: Any = None
    feed_mm_min: float | None = None


#: Explicit segment kind -> its option class.
SEGMENT_KINDS: dict[str, type[LineSpec] | type[ArcSpec]] = {"line": LineSpec, "arc": ArcSpec}


@dataclass(frozen=True)
class ExplicitProgram:
    """Options of an explicit program: ``segments`` from ``start_mm`` over ``axes``."""

    segments: Any
    axes: Any = ("x", "y")
    start_mm: Any = None
    feed_mm_min: float | None = None

    def __post_init__(self) -> None:
        if self.feed_mm_min is not None:
            require_feed_mm_min("feed_mm_min", self.feed_mm_min, "program")
        if isinstance(self.segments, (str, Mapping)) or not isinstance(self.segments, Sequence) or not self.segments:
            raise ConfigError(f"program.segments must be a non-empty list, got {self.segments!r}")


@dataclass(frozen=True)
class GcodeOptions:
    """Options of a G-code program (the text or file comes from the source key)."""

    axes: Any = ("x", "y", "z")
    rapid_feed_mm_min: float = 1000.0
    start_mm: Any = None
    work_offsets_mm: Any = None


#: Planes of the axes x, y, z in G-code's orientation (G17 XY, G19 YZ, G18 ZX: ccw seen from the third axis).
RIGHT_HANDED_PLANES = frozenset({("x", "y"), ("y", "z"), ("z", "x")})


def _plane(value: Any, axes: tuple[str, ...], context: str) -> tuple[int, int]:
    """Axis indices of a plane given as two axis names (``"xy"`` or ``[x, y]``); default the first two.

    Two of x, y, z name a plane in either order and are oriented as in
    G-code (:data:`RIGHT_HANDED_PLANES`: ``xz`` is G18's ZX, so ``ccw`` turns
    as G18 G3); other names keep the order given (ccw from the first toward the second).
    """
    if value is None:
        return (0, 1)
    names = list(value) if isinstance(value, str) and len(value) == 2 and value not in axes else value
    try:
        a, b = (axes.index(str(n)) for n in names)
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{context}.plane must name two of the axes {list(axes)}, got {value!r}") from err
    if a == b:
        raise ConfigError(f"{context}.plane must name two different axes, got {value!r}")
    if (str(names[1]).lower(), str(names[0]).lower()) in RIGHT_HANDED_PLANES:
        return b, a
    return a, b


def _segment_feed_m_s(spec: LineSpec | ArcSpec, default_mm_min: float | None, context: str) -> float:
    feed = spec.feed_mm_min if spec.feed_mm_min is not None else default_mm_min
    if feed is None:
        raise ConfigError(f"{context}.feed_mm_min is required (the program has no feed_mm_min)")
    return mm_min_to_m_s(require_feed_mm_min("feed_mm_min", feed, context))


def _explicit_segment(item: Any, start_mm: FloatArray, options: ExplicitProgram,
                      axes: tuple[str, ...], context: str) -> tuple[Segment, FloatArray]:
    """One explicit segment from ``start_mm``; returns it and its end point (mm)."""
    if not isinstance(item, Mapping) or len(item) != 1:
        raise ConfigError(f"{context} must be a mapping with one key of {sorted(SEGMENT_KINDS)}, got {item!r}")
    kind, body = next(iter(item.items()))
    require_choice("kind", kind, SEGMENT_KINDS, context)
    context = f"{context}.{kind}"
    spec = build_config(SEGMENT_KINDS[kind], body, context)
    end_mm = _point_mm("to_mm", spec.to_mm, len(axes), context)
    feed_m_s = _segment_feed_m_s(spec, options.feed_mm_min, context)
    if isinstance(spec, LineSpec):
        return LineSegment(mm_to_m(start_mm), mm_to_m(end_mm), feed_m_s), end_mm
    center_mm = _point_mm("center_mm", spec.center_mm, len(axes), context)
    require_choice("direction", spec.direction, DIRECTIONS, context)
    segment = ArcSegment(mm_to_m(start_mm), mm_to_m(end_mm), mm_to_m(center_mm), DIRECTIONS[spec.direction],
                         _plane(spec.plane, axes, context), feed_m_s)
    return segment, end_mm


def _from_segments(body: dict[str, Any], name: str, base_dir: Path | None) -> Program:
    options = build_config(ExplicitProgram, body, "program")
    axes = _axes(options.axes, "program")
    position_mm = _point_mm("start_mm", options.start_mm, len(axes), "program")
    segments = []
    for index, item in enumerate(options.segments):
        try:
            segment, position_mm = _explicit_segment(item, position_mm, options, axes, f"program.segments[{index}]")
        except ProgramError as err:
            raise ProgramError(f"{name}: segment {index}: {err}") from err
        segments.append(segment)
    return Program(name, axes, tuple(segments))


def _from_shape(body: dict[str, Any], name: str, base_dir: Path | None) -> Program:
    shape = body.pop("shape")
    require_choice("shape", shape, SHAPES, "program")
    options = build_config(SHAPES[shape], body, "program")
    axes = _axes(options.axes, "program")
    if len(axes) < 2:
        raise ConfigError(f"program.axes must name at least two axes for shape {shape!r}, got {list(axes)}")
    start_mm = _point_mm("start_mm", options.start_mm, len(axes), "program")
    return Program(name, axes, tuple(options.segments(start_mm)))


def _check_gcode_options(options: GcodeOptions) -> None:
    """The numbers of a G-code program's options, each by its name and bound (their shapes are the reader's)."""
    require_feed_mm_min("rapid_feed_mm_min", options.rapid_feed_mm_min, "program")
    if isinstance(options.start_mm, (list, tuple)):
        for j, value in enumerate(options.start_mm):
            require_extent_mm(f"start_mm[{j}]", value, "program")
    if isinstance(options.work_offsets_mm, Mapping):
        for key, offset in options.work_offsets_mm.items():
            for j, value in enumerate(offset if isinstance(offset, (list, tuple)) else ()):
                require_extent_mm(f"work_offsets_mm.{key}[{j}]", value, "program")


def _gcode(text: str, body: dict[str, Any], name: str) -> Program:
    options = build_config(GcodeOptions, body, "program")
    _check_gcode_options(options)
    return parse_gcode(text, _axes(options.axes, "program"), rapid_feed_mm_min=options.rapid_feed_mm_min,
                       start_mm=options.start_mm, name=name, work_offsets_mm=options.work_offsets_mm)


def _from_gcode(body: dict[str, Any], name: str, base_dir: Path | None) -> Program:
    text = body.pop("gcode")
    if not isinstance(text, str):
        raise ConfigError(f"program.gcode must be G-code text, got {type(text).__name__}")
    return _gcode(text, body, name)


def _from_gcode_file(body: dict[str, Any], name: str, base_dir: Path | None) -> Program:
    path = Path(str(body.pop("gcode_file")))
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    return _gcode(read_gcode_file(path, "program.gcode_file", ConfigError), body, name)


#: Source key -> builder of the program from the rest of the section.
SOURCES: dict[str, Callable[[dict[str, Any], str, Path | None], Program]] = {
    "segments": _from_segments, "shape": _from_shape, "gcode": _from_gcode, "gcode_file": _from_gcode_file}


def load_program(mapping: Mapping[str, Any], name: str = "program", base_dir: str | Path | None = None) -> Program:
    """Build a program from a scenario's ``program:`` section.

    Parameters
    ----------
    mapping : mapping
        The section (mm, mm/min, deg); see the module docstring for its forms.
    name : str
        Program name unless the section has a ``name`` key.
    base_dir : str or Path, optional
        Directory that a relative ``gcode_file`` is read from (e.g. the scenario's).

    Raises
    ------
    ConfigError
        For an unknown key or shape, a missing key or a value out of range.
    ProgramError
        For a contour that cannot be built (an arc end off its circle, gaps).
    """
    if not isinstance(mapping, Mapping):
        raise ConfigError(f"program must be a mapping, got {type(mapping).__name__}")
    body = dict(mapping)
    name = str(body.pop("name", name))
    sources = [key for key in SOURCES if key in body]
    if len(sources) != 1:
        raise ConfigError(f"program needs exactly one of {sorted(SOURCES)}, got keys {sorted(body)}")
    return SOURCES[sources[0]](body, name, None if base_dir is None else Path(base_dir))
