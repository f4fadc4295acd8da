"""PNG reports of recorded runs (matplotlib, Agg canvas, no pyplot state).

Runs are labelled by name (``<scenario>/<start time>`` for a run folder);
runs of the same name are told apart by their source (:func:`run_labels`).

Figures, chosen by name from ``FIGURES``:

- ``xy``: each run's measured trace beside the programmed contour, the
  deviation normal to the contour magnified ``M`` times (``q + M (p - q)``,
  ``q`` the nearest contour point), as the papers draw it; one panel per run;
- ``error_time`` / ``error_path``: exact contour error (µm) against time and
  against path length, runs overlaid (the path-length trace breaks where the
  nearest point jumps across a closed contour's start, :func:`path_trace`);
- ``circular``: polar circular-test plot (radial deviation in µm about the
  nominal circle, reversals marked), one panel per circle run;
- ``tracking``: per axis, tracking error (µm) and servo command, runs overlaid.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from cnc_contour_control.core.config import require_choice, require_positive
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.units import M_PER_MM, M_PER_UM
from cnc_tools.analysis.scoring import Score, score_run, tracking_errors
from cnc_tools.run_record import RecordedRun

#: Share of the contour's size the largest magnified error should span when M is chosen automatically.
AUTO_ERROR_SHARE = 0.08
#: Points drawn per programmed segment.
POINTS_PER_SEGMENT = 400


@dataclass(frozen=True, eq=False)
class _Item:
    """One run with its score and its label in legends and titles."""

    run: RecordedRun
    score: Score
    label: str


def run_labels(runs: Sequence[RecordedRun]) -> list[str]:
    """One distinct label per run: its name, with its source (then its position) when names repeat."""
    names = [run.name for run in runs]
    labels = [name if names.count(name) == 1 else f"{name} ({run.source})" for name, run in zip(names, runs)]
    return [label if labels.count(label) == 1 else f"{label} #{k + 1}" for k, label in enumerate(labels)]


def path_trace(path_length_m: np.ndarray, error_m: np.ndarray, total_length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Contour error against path length [mm, µm], NaN-separated where the path length jumps.

    A sample's nearest contour point jumps from the end of a closed contour to
    its start (or back) when the tool passes the start point; a jump of more
    than half the contour's length is such a wrap, and a NaN between the two
    samples keeps the plot from drawing a line across the whole figure.

    Parameters
    ----------
    path_length_m : (N,) array
        Arc length of each sample's nearest contour point [m].
    error_m : (N,) array
        Exact contour error of each sample [m].
    total_length_m : float
        The programmed contour's length [m].

    Returns
    -------
    tuple of (M,) arrays
        Path length [mm] and error [µm], ``M = N +`` the number of wraps.
    """
    x_mm, y_um = np.asarray(path_length_m) / M_PER_MM, np.asarray(error_m) / M_PER_UM
    wraps = np.flatnonzero(np.abs(np.diff(path_length_m)) > 0.5 * total_length_m) + 1
    return np.insert(x_mm, wraps, np.nan), np.insert(y_um, wraps, np.nan)


def nice_magnification(run_items: Sequence[RecordedRun], scores: Sequence[Score]) -> float:
    """A 1-2-5 magnification so the largest contour error spans ``AUTO_ERROR_SHARE`` of the contour size."""
    size_m = max(float(np.ptp(_contour_points(r), axis=0).max()) for r in run_items)
    error_m = max((float(np.max(s.series.error_m, initial=0.0)) for s in scores), default=0.0)
    if error_m <= 0.0 or size_m <= 0.0:
        return 1.0
    raw = AUTO_ERROR_SHARE * size_m / error_m
    decade = 10.0 ** math.floor(math.log10(raw))
    return max(step * decade for step in (1.0, 2.0, 5.0) if step * decade <= raw)


def _contour_points(run: RecordedRun) -> np.ndarray:
    """(M, n_axes) points along the programmed contour, m."""
    return np.concatenate([seg.point(np.linspace(0.0, seg.length_m, POINTS_PER_SEGMENT))
                           for seg in run.program.segments])


def _nearest_points(item: _Item) -> np.ndarray:
    """(N, n_axes) nearest contour point of every scored sample, m."""
    series, program = item.score.series, item.run.program
    out = np.empty_like(series.position_m)
    for index in np.unique(series.segment_index):
        rows = series.segment_index == index
        out[rows] = program.segments[index].point(series.path_length_m[rows] - program.segment_start_m[index])
    return out


def _plane(run: RecordedRun) -> tuple[int, int]:
    arcs = [seg.plane for seg in run.program.segments if hasattr(seg, "plane")]
    return tuple(arcs[0]) if arcs else (0, 1)


def _xy(items: Sequence[_Item], magnification: float) -> Figure:
    fig = Figure(figsize=(5.0 * len(items), 5.0), layout="constrained")
    for k, item in enumerate(items):
        ax = fig.add_subplot(1, len(items), k + 1)
        a, b = _plane(item.run)
        contour = _contour_points(item.run) / M_PER_MM
        nearest = _nearest_points(item)
        trace = (nearest + magnification * (item.score.series.position_m - nearest)) / M_PER_MM
        ax.plot(contour[:, a], contour[:, b], color="0.6", lw=1.0, label="programmed")
        ax.plot(trace[:, a], trace[:, b], lw=0.9, label=f"measured, error ×{magnification:g}")
        ax.set_aspect("equal", adjustable="datalim")
        names = item.run.axis_names
        ax.set(title=item.label, xlabel=f"{names[a]} [mm]", ylabel=f"{names[b]} [mm]")
        ax.legend(loc="best", fontsize="small")
    return fig


def _error_vs(items: Sequence[_Item], axis: str) -> Figure:
    fig = Figure(figsize=(9.0, 4.0), layout="constrained")
    ax = fig.add_subplot()
    for item in items:
        series = item.score.series
        if axis == "time":
            x, y = series.time_s, series.error_m / M_PER_UM
        else:
            x, y = path_trace(series.path_length_m, series.error_m, item.run.program.total_length_m)
        ax.plot(x, y, lw=0.8, label=item.label)
    title = f"exact contour error vs {'time' if axis == 'time' else 'path length'}"
    ax.set(xlabel="time [s]" if axis == "time" else "path length [mm]", ylabel="contour error [µm]",
           title=title if len(items) > 1 else f"{items[0].label}: {title}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig


def _polar_panel(ax: Axes, item: _Item) -> None:
    test = item.score.circular
    assert test is not None
    deviation_um = test.radial_deviation_m / M_PER_UM
    low, high = float(np.min(deviation_um)), float(np.max(deviation_um))
    span = max(high - low, abs(high), abs(low), 1e-3)
    ax.plot(test.angle_rad, deviation_um, lw=0.8, label="radial deviation")
    ax.plot(np.linspace(0, 2 * np.pi, 361), np.zeros(361), color="0.5", lw=0.8, ls="--", label="nominal radius")
    for reversal in test.reversals:
        ax.plot(math.radians(reversal.angle_deg), reversal.peak_radial_deviation_m / M_PER_UM, "rv", ms=5)
    ax.set_ylim(min(low, 0.0) - 0.2 * span, max(high, 0.0) + 0.2 * span)
    ax.set_rorigin(min(low, 0.0) - 1.5 * span)  # type: ignore[attr-defined]  # a PolarAxes (projection="polar")
    ax.yaxis.set_major_locator(MaxNLocator(4))
    ax.set_rlabel_position(67.5)  # type: ignore[attr-defined]  # a PolarAxes, as above
    ax.tick_params(axis="y", labelsize="x-small")
    ax.set_title(f"{item.label}: R = {test.circle.radius_m / M_PER_MM:g} mm, "
                 f"G = {test.circular_deviation_m / M_PER_UM:.3g} µm\n(radial axis: deviation [µm])",
                 fontsize="small")


def _circular(items: Sequence[_Item], magnification: float) -> Figure | None:
    circles = [item for item in items if item.score.circular is not None]
    if not circles:
        return None
    fig = Figure(figsize=(5.0 * len(circles), 5.2), layout="constrained")
    for k, item in enumerate(circles):
        _polar_panel(fig.add_subplot(1, len(circles), k + 1, projection="polar"), item)
    return fig


def _tracking(items: Sequence[_Item], magnification: float) -> Figure:
    axes_names = items[0].run.axis_names
    fig = Figure(figsize=(11.0, 2.6 * len(axes_names)), layout="constrained")
    grid = fig.subplots(len(axes_names), 2, squeeze=False, sharex=True)
    for item in items:
        stamps, error = tracking_errors(item.run)
        for k, axis in enumerate(item.run.axis_names[:len(axes_names)]):
            grid[k, 0].plot(stamps * 1e-9, error[:, k] / M_PER_UM, lw=0.8, label=item.label)
            command = item.run.commands.get(axis)
            if command is not None:
                grid[k, 1].plot(command.stamp_ns * 1e-9, command.command, lw=0.8,
                                label=f"{item.label} [{command.command_unit}]")
    for k, axis in enumerate(axes_names):
        grid[k, 0].set(ylabel=f"{axis} tracking error [µm]")
        grid[k, 1].set(ylabel=f"{axis} command")
        for ax in grid[k]:
            ax.grid(True, alpha=0.3)
            if ax.lines:
                ax.legend(loc="best", fontsize="small")
            else:
                ax.text(0.5, 0.5, "not recorded", ha="center", va="center", transform=ax.transAxes)
    grid[-1, 0].set(xlabel="time [s]")
    grid[-1, 1].set(xlabel="time [s]")
    return fig


#: Figure name -> (file name, builder(items, magnification) -> Figure or None when not applicable).
FIGURES: dict[str, tuple[str, Callable[[Sequence[_Item], float], Figure | None]]] = {
    "xy": ("xy_trace.png", _xy),
    "error_time": ("contour_error_time.png", lambda items, m: _error_vs(items, "time")),
    "error_path": ("contour_error_path.png", lambda items, m: _error_vs(items, "path")),
    "circular": ("circular_test.png", _circular),
    "tracking": ("tracking.png", _tracking),
}


def write_report(runs: Sequence[RecordedRun], out_dir: str | Path, *, scores: Sequence[Score] | None = None,
                 figures: Sequence[str] | None = None, magnification: float | None = None,
                 dpi: int = 120) -> list[Path]:
    """Write the PNG figures of one or more runs (side by side or overlaid, labelled by :func:`run_labels`).

    Parameters
    ----------
    runs
        Recorded runs (``bag.read_bag``); at least one.
    out_dir
        Folder for the PNGs (created; files of the same name are replaced).
    scores
        Their scores, one per run; computed when omitted.
    figures
        Names from ``FIGURES``; default all.
    magnification
        Factor on the contour-normal deviation in the XY plot; default a 1-2-5 value
        chosen so the largest error spans 8 % of the contour.
    dpi
        Resolution of the PNGs.

    Returns
    -------
    list of Path
        The files written, in ``FIGURES`` order (figures that do not apply, e.g.
        ``circular`` without a circle program, are skipped).
    """
    if not runs:
        raise ConfigError("runs must hold at least one recorded run")
    scored = list(scores) if scores is not None else [score_run(run) for run in runs]
    if len(scored) != len(runs):
        raise ConfigError(f"scores must have one entry per run ({len(runs)}), got {len(scored)}")
    names = list(FIGURES) if figures is None else [require_choice("figures", n, FIGURES) for n in figures]
    factor = (nice_magnification(runs, scored) if magnification is None
              else require_positive("magnification", magnification))
    items = [_Item(run, score, label) for run, score, label in zip(runs, scored, run_labels(runs))]
    folder = Path(out_dir)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names:
        file_name, build = FIGURES[name]
        figure = build(items, factor)
        if figure is not None:
            FigureCanvasAgg(figure)
            figure.savefig(folder / file_name, dpi=dpi)
            written.append(folder / file_name)
    return written
