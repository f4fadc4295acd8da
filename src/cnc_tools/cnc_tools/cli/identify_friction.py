"""``cnc-contour identify-friction``: paper 000's friction identification through the node graph.

Runs every planned speed (:mod:`cnc_tools.identification.friction`) on the nominal plant
and on the varied plants, through the node graph (one recorded bag per run)
or with ``--engine`` in-process, then writes ``points.csv``, ``curve.csv``,
``friction_velocity.png`` and the fitted ``friction_table.yaml`` and prints
the identified points beside the model the plant ran.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import queue
import random
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from cnc_contour_control.core.errors import CncError, ConfigError, FaultError
from cnc_plant_sim.models.friction import PiecewiseQuadraticFriction
from cnc_plant_sim.models.plant import make_plant
from cnc_tools.bagio.bag import RecordedRun, read_bag
from cnc_tools.identification import friction as fid
from cnc_tools.identification import friction_curve as fcurve
from cnc_tools.runs.dds import MAX_RANDOM_DOMAIN_ID, loopback_env
from cnc_tools.runs.engine import run_engine
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.graph import run_graph
from cnc_tools.runs.progress import Task
from cnc_tools.runs.progress import task as progress_task
from cnc_tools.runs.scenario import load_scenario

Report = Callable[[int, fid.FrictionPoint], None]


# =========================================================================== traces of one run
def trace_from_engine(run: fid.SpeedRun, index: int) -> tuple[fid.AxisTrace, Mapping[str, Any]]:
    """Run the scenario in-process; the axis trace and the plant as drawn."""
    result = run_engine(run.scenario)
    reference = result.reference
    assert reference is not None  # an engine run always has its references
    trace = fid.AxisTrace(result.time_s, result.joint_states.position_m[:, index], reference.position_m[:, index],
                          reference.velocity_m_s[:, index], result.command_array()[:, index])
    return trace, make_plant(run.scenario.plant).describe()


def trace_from_bag(recorded: RecordedRun, axis: str) -> fid.AxisTrace:
    """The axis trace of a recorded run, rows matched by header stamp."""
    index = recorded.axis_names.index(axis)
    joints, reference, commands = recorded.joint_states, recorded.reference, recorded.commands.get(axis)
    if reference is None or commands is None:
        raise FaultError(f"bag {recorded.source} lacks the reference or the servo/{axis}/command topic")
    stamps = np.intersect1d(np.intersect1d(joints.stamp_ns, reference.stamp_ns), commands.stamp_ns)
    rows = [np.searchsorted(series, stamps) for series in (joints.stamp_ns, reference.stamp_ns, commands.stamp_ns)]
    return fid.AxisTrace(stamps * np.float64(1e-9), joints.position_m[rows[0], index],
                         reference.position_m[rows[1], index], reference.velocity_m_s[rows[1], index],
                         commands.command[rows[2]])


def graph_point(run: fid.SpeedRun, constants: fid.AxisConstants, config: fid.IdentificationConfig,
                run_dir: Path, env: Mapping[str, str] | None) -> fid.FrictionPoint:
    """One run through the node graph, recorded to ``run_dir/bag``, and its identified point."""
    result = run_graph(run.scenario, run_dir, record=True, env=env)
    if result.faults or result.bag_path is None:
        raise FaultError(f"run {run.plant_label} {run.label} in {run_dir} faulted: {'; '.join(result.faults)}")
    trace = trace_from_bag(read_bag(result.bag_path), constants.axis)
    drawn = fid.DrawnAxis.from_description(result.summary["plant"], constants.axis)
    return fid.estimate_point(trace, run, constants, drawn, config)


def engine_point(run: fid.SpeedRun, constants: fid.AxisConstants,
                 config: fid.IdentificationConfig) -> fid.FrictionPoint:
    """One run in-process and its identified point."""
    trace, plant = trace_from_engine(run, constants.axis_index)
    return fid.estimate_point(trace, run, constants, fid.DrawnAxis.from_description(plant, constants.axis), config)


def run_all(runs: Sequence[fid.SpeedRun], constants: fid.AxisConstants, config: fid.IdentificationConfig,
            out_dir: Path, engine: bool, jobs: int, report: Report) -> list[fid.FrictionPoint]:
    """Every run in order (``jobs`` node graphs at once, each on its own DDS domain); points in run order."""
    if engine:
        points = [engine_point(run, constants, config) for run in runs]
        for i, point in enumerate(points):
            report(i, point)
        return points
    domains: queue.Queue[int | None] = queue.Queue()
    for domain in (random.SystemRandom().sample(range(1, MAX_RANDOM_DOMAIN_ID + 1), jobs) if jobs > 1 else [None]):
        domains.put(domain)

    def task(run: fid.SpeedRun) -> fid.FrictionPoint:
        domain = domains.get()
        try:
            env = None if domain is None else loopback_env(domain_id=domain)
            return graph_point(run, constants, config, out_dir / run.plant_label / run.label, env)
        finally:
            domains.put(domain)

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures: list[Future[fid.FrictionPoint]] = [pool.submit(task, run) for run in runs]
        try:
            points = []
            for i, future in enumerate(futures):
                points.append(future.result())
                report(i, points[-1])
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    return points


# =========================================================================== files
def write_points_csv(path: Path, points: Sequence[fid.FrictionPoint]) -> Path:
    """Every run's point (one row per plant and speed)."""
    names = [f.name for f in dataclasses.fields(fid.FrictionPoint)] + ["deviation_dac"]
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(names)
        for p in points:
            writer.writerow([_cell(getattr(p, n)) for n in names])
    return path


def write_curve_csv(path: Path, summaries: Sequence[fcurve.SpeedSummary]) -> Path:
    """One row per signed speed: nominal point, model, and the varied plants' band."""
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["velocity_mm_s", "friction_nominal_dac", "model_nominal_dac", "deviation_nominal_dac",
                         "ripple_nominal_counts", "status_nominal", "varied_steady", "varied_mean_dac",
                         "varied_std_dac", "varied_min_dac", "varied_max_dac", "varied_half_range_dac"])
        for s in summaries:
            n = s.nominal
            writer.writerow([_cell(v) for v in (s.velocity_mm_s, n.friction_dac, n.model_nominal_dac,
                                                n.deviation_dac, n.ripple_counts, n.status,
                                                sum(p.status == "steady" for p in s.varied), *s.band_dac,
                                                s.half_range_dac)])
    return path


def _cell(value: Any) -> Any:
    return f"{value:.6g}" if isinstance(value, float) else ("" if value is None else value)


# =========================================================================== figure (Figs 3-4 style)
def _model_curves(ax: Axes, constants: fid.AxisConstants, top_mm_s: float, friction_pct: float) -> None:
    for sign in (1, -1):
        v = sign * np.linspace(1e-6, top_mm_s, 400)
        f = np.array([constants.friction.force(x) for x in v])
        ax.plot(v, f, "k-", lw=1.2, label="model the plant ran (Eq. 15)" if sign > 0 else None)
        if friction_pct > 0:
            ax.fill_between(v, f * (1 - friction_pct / 100), f * (1 + friction_pct / 100), color="0.85",
                            label=f"Eq. 15 ±{friction_pct:g} % (drawn scale range)" if sign > 0 else None)


def _points_panel(ax: Axes, summaries: Sequence[fcurve.SpeedSummary],
                  fits: tuple[fcurve.BranchFit, fcurve.BranchFit] | None,
                  top_mm_s: float) -> None:
    v = np.array([s.velocity_mm_s for s in summaries])
    band = np.array([s.band_dac for s in summaries])
    has_band = np.isfinite(band[:, 0])
    if has_band.any():
        ax.errorbar(v[has_band], band[has_band, 0], yerr=[band[has_band, 0] - band[has_band, 2],
                    band[has_band, 3] - band[has_band, 0]], fmt="s", ms=3, color="tab:orange", capsize=2,
                    label="varied plants: mean, min–max (run-to-run)")
    nominal = [s.nominal for s in summaries]
    steady = np.array([p.status == "steady" for p in nominal])
    f_nom = np.array([p.friction_dac for p in nominal])
    ax.plot(v[steady], f_nom[steady], "o", ms=4, color="tab:blue", label="identified, nominal plant")
    if (~steady).any():
        ax.plot(v[~steady], f_nom[~steady], "x", ms=7, color="tab:red", label="no steady state (stick-slip)")
    if fits is not None:
        for fit in fits:
            x = fit.direction * np.linspace(1e-6, top_mm_s, 400)
            ax.plot(x, fit.force(x), "--", color="tab:green", lw=1.0,
                    label="fitted (quadratic + constant)" if fit.direction > 0 else None)


def _residual_panel(ax: Axes, points: Sequence[fid.FrictionPoint]) -> None:
    for seed_kind, colour, label in ((False, "tab:blue", "nominal plant"),
                                     (True, "tab:orange", "varied plants (nominal K)")):
        chosen = [p for p in points if (p.seed is not None) == seed_kind and p.status == "steady"]
        ax.plot([p.velocity_mm_s for p in chosen], [p.deviation_dac for p in chosen], "o" if not seed_kind else "s",
                ms=3, color=colour, label=label)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("velocity V_r [mm/s]")
    ax.set_ylabel("identified − model [DAC]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def write_figure(path: Path, points: Sequence[fid.FrictionPoint], summaries: Sequence[fcurve.SpeedSummary],
                 constants: fid.AxisConstants, fits: tuple[fcurve.BranchFit, fcurve.BranchFit] | None,
                 friction_pct: float) -> Path:
    """Friction force against velocity (both branches) with the model overlaid, and the residuals."""
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1.3))
    top_mm_s = max(abs(s.velocity_mm_s) for s in summaries) * 1.05
    _model_curves(top, constants, top_mm_s, friction_pct)
    _points_panel(top, summaries, fits, top_mm_s)
    top.axhline(0.0, color="k", lw=0.5)
    top.axvline(0.0, color="k", lw=0.5)
    top.set_ylabel("friction force F_d [DAC units]")
    top.set_title(f"Friction–velocity curve, axis {constants.axis} "
                  "(paper 000, Section 2: F_d = K_p e_ss − V_r/(K K_e))")
    top.grid(True, alpha=0.3)
    top.legend(fontsize=7, loc="center right")
    _residual_panel(bottom, points)
    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=120)
    return path


# =========================================================================== printing
def print_points(summaries: Sequence[fcurve.SpeedSummary]) -> None:
    """The identified points beside the model, one row per signed speed."""
    print(f"  {'V_r':>7} {'F_d nom':>8} {'Eq.15':>7} {'diff':>6} {'quant':>6} | {'varied':>6} {'min':>6} "
          f"{'max':>6} {'±half':>5} | status")
    for s in summaries:
        n, (mean, _, low, high) = s.nominal, s.band_dac
        print(f"  {s.velocity_mm_s:+7.2f} {n.friction_dac:8.2f} {n.model_dac:7.2f} {n.deviation_dac:+6.2f} "
              f"{n.quantisation_dac:+6.2f} | {mean:6.2f} {low:6.2f} {high:6.2f} {s.half_range_dac:5.2f} | {n.status}"
              + (f" (stopped {100 * n.stopped_fraction:.0f} % of the window)" if n.status != "steady" else ""))


def agreement(points: Sequence[fid.FrictionPoint], summaries: Sequence[fcurve.SpeedSummary]) -> dict[str, float]:
    """The agreement figures: identified against the model the plant ran, and the run-to-run band."""
    steady = [p for p in points if p.status == "steady"]
    nominal = [p for p in steady if p.seed is None]
    varied = [p for p in steady if p.seed is not None]
    inside = [abs(s.nominal.deviation_dac) <= s.half_range_dac for s in summaries
              if s.nominal.status == "steady" and math.isfinite(s.half_range_dac)]
    return {
        "nominal_max_abs_dev_dac": _max_abs(p.deviation_dac for p in nominal),
        "nominal_rms_dev_dac":
            float(np.sqrt(np.mean([p.deviation_dac ** 2 for p in nominal]))) if nominal else math.nan,
        "max_abs_quantisation_dac": _max_abs(p.quantisation_dac for p in steady),
        "varied_max_abs_dev_dac": _max_abs(p.deviation_dac for p in varied),
        "varied_true_gain_max_abs_dev_dac": _max_abs(p.friction_true_gain_dac - p.model_dac for p in varied),
        "band_half_range_median_dac": _median([s.half_range_dac for s in summaries]),
        "nominal_inside_band": float(sum(inside)), "speeds_with_band": float(len(inside)),
    }


def _median(values: Sequence[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.median(finite)) if finite else math.nan


def _max_abs(values: Any) -> float:
    items = [abs(v) for v in values]
    return max(items) if items else math.nan


def print_agreement(figures: Mapping[str, float]) -> None:
    """The agreement figures in words."""
    print(f"  nominal plant: |identified − Eq. 15| max {figures['nominal_max_abs_dev_dac']:.3f} DAC, "
          f"RMS {figures['nominal_rms_dev_dac']:.3f} DAC; mean quantisation bias max "
          f"{figures['max_abs_quantisation_dac']:.3f} DAC")
    if not math.isnan(figures["varied_max_abs_dev_dac"]):
        print(f"  varied plants: |identified − Eq. 15 × drawn scale| max {figures['varied_max_abs_dev_dac']:.3f} DAC "
              f"with the nominal K ({figures['varied_true_gain_max_abs_dev_dac']:.3f} DAC with the drawn K); "
              f"run-to-run half-range median {figures['band_half_range_median_dac']:.3f} DAC")
    if figures["speeds_with_band"] > 0:
        print(f"  nominal identification within the run-to-run half-range at "
              f"{figures['nominal_inside_band']:.0f} of {figures['speeds_with_band']:.0f} steady speeds")


def print_fits(fits: tuple[fcurve.BranchFit, fcurve.BranchFit], constants: fid.AxisConstants) -> None:
    """The fitted coefficients beside Eq. 15's (when the plant runs a paper-000 model)."""
    paper = constants.friction if isinstance(constants.friction, PiecewiseQuadraticFriction) else None
    for fit in fits:
        c2, c1, c0 = fit.coefficients_dac
        line = f"  fit {'V > 0' if fit.direction > 0 else 'V < 0'}: {c2:+.4f} V² {c1:+.3f} V {c0:+.2f}"
        if fit.high_dac is not None:
            line += f" for |V| < {fit.limit_speed_mm_s:.2f}, {fit.high_dac:.2f} beyond"
        if paper is not None:
            p2, p1, p0 = paper.positive_coefficients if fit.direction > 0 else paper.negative_coefficients
            high = paper.positive_high_dac if fit.direction > 0 else paper.negative_high_dac
            line += (f"   (Eq. 15: {p2:+.2f} V² {p1:+.2f} V {p0:+.2f} for |V| < {paper.limit_speed_mm_s:g}, "
                     f"{high:.2f} beyond)")
        print(line + f"; RMS residual {fit.rms_dac:.3f} DAC")


# =========================================================================== the subcommand
def _speeds(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(item) for item in text.split(",") if item.strip())
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"--speeds takes comma-separated numbers in mm/s, got {text!r}") from err


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--axis", default="x", help="axis to identify (default x)")
    parser.add_argument("--speeds", type=_speeds, default=fid.DEFAULT_SPEEDS_MM_S, metavar="V1,V2,...",
                        help="speed magnitudes in mm/s, each run in both directions "
                             f"(default {','.join(f'{v:g}' for v in fid.DEFAULT_SPEEDS_MM_S)})")
    parser.add_argument("--kp", type=float, default=2.4, help="P gain, DAC units per BLU (default 2.4)")
    parser.add_argument("--seeds", type=int, default=4, help="varied plants (seeds 1..N) besides the nominal one")
    parser.add_argument("--settle-s", type=float, default=1.0, help="wait after the ramp before averaging, s")
    parser.add_argument("--window-s", type=float, default=2.0, help="averaging window, s")
    parser.add_argument("--scenario", type=Path, help="take plant, limits, T and DAC from this scenario "
                                                      "(default: paper 000's plant, T = 10 ms, 8-bit DAC)")
    parser.add_argument("--engine", action="store_true", help="run in-process (fast, no DDS, no bags)")
    parser.add_argument("--jobs", type=int, default=2, help="node graphs run at once, each on its own domain")
    parser.add_argument("--out", type=Path, help="output folder (default bags/friction_id/<axis>/<timestamp>)")
    parser.add_argument("--write-table", type=Path, metavar="PATH", help="also write the fitted table YAML here")


def _config(args: argparse.Namespace) -> fid.IdentificationConfig:
    if args.seeds < 0:
        raise ConfigError(f"--seeds must be >= 0, got {args.seeds}")
    if args.jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {args.jobs}")
    return fid.IdentificationConfig(axis=args.axis, speeds_mm_s=tuple(args.speeds), kp_dac_per_count=args.kp,
                                    seeds=tuple(range(1, args.seeds + 1)), settle_s=args.settle_s,
                                    window_s=args.window_s)


def _progress(total: int, runs: Task) -> Report:
    def report(index: int, p: fid.FrictionPoint) -> None:
        print(f"  [{index + 1:3d}/{total}] {p.plant_label:<8} V_r = {p.velocity_mm_s:+7.2f} mm/s  "
              f"F_d = {p.friction_dac:+7.2f} DAC  (model {p.model_dac:+7.2f})  {p.status}", flush=True)
        runs.step()
    return report


def identify_friction(args: argparse.Namespace) -> int:
    """Identify an axis's friction–velocity curve (paper 000, Section 2) and write points, plot and table."""
    config = _config(args)
    template = dict(load_scenario(args.scenario).raw) if args.scenario else fid.DEFAULT_TEMPLATE
    constants, runs = fid.plan_runs(template, config)
    out_dir = args.out or project_root() / "bags" / "friction_id" / config.axis / timestamp()
    if out_dir.exists() and any(out_dir.iterdir()):
        raise CncError(f"--out folder {out_dir} exists and is not empty; runs are never overwritten")
    out_dir.mkdir(parents=True, exist_ok=True)
    how = "in-process engine" if args.engine else f"node graph, {args.jobs} at once, one bag per run"
    print(f"identifying axis {config.axis}: {len(config.signed_speeds_mm_s)} speeds × {1 + len(config.seeds)} "
          f"plants = {len(runs)} runs ({how}), K_p = {config.kp_dac_per_count:g}, K = "
          f"{constants.gain_blu_s_per_dac:g} BLU/s per DAC, K_e = {constants.encoder_counts_per_blu:g}", flush=True)
    with progress_task("friction runs", len(runs)) as done:
        points = run_all(runs, constants, config, out_dir, args.engine, args.jobs, _progress(len(runs), done))
    summaries = fcurve.summarise(points)
    return _outputs(args, config, constants, points, summaries, out_dir, runs[-1])


def _outputs(args: argparse.Namespace, config: fid.IdentificationConfig, constants: fid.AxisConstants,
             points: list[fid.FrictionPoint], summaries: list[fcurve.SpeedSummary], out_dir: Path,
             last: fid.SpeedRun) -> int:
    print_points(summaries)
    figures = agreement(points, summaries)
    print_agreement(figures)
    try:
        fits: tuple[fcurve.BranchFit, fcurve.BranchFit] | None = fcurve.fit_curve([s.nominal for s in summaries])
    except ConfigError as err:
        print(f"  no fitted curve: {err}")
        fits = None
    files = [write_points_csv(out_dir / "points.csv", points), write_curve_csv(out_dir / "curve.csv", summaries),
             write_figure(out_dir / "friction_velocity.png", points, summaries, constants, fits,
                          last.scenario.plant.options().friction_pct if config.seeds else 0.0)]
    if fits is not None:
        print_fits(fits, constants)
        table = fcurve.fitted_table(fits, max(config.speeds_mm_s))
        meta = _meta(config, constants, figures, args.engine)
        paths = (out_dir / "friction_table.yaml", *([args.write_table] if args.write_table else []))
        files += [fcurve.write_table(path, table, fits, meta) for path in paths]
    if not args.engine:
        print(f"bags:  {out_dir}/<plant>/<speed>/bag ({len(points)} runs)")
    for path in files:
        print(f"wrote: {path}")
    return 0 if fits is not None else 1


def _meta(config: fid.IdentificationConfig, constants: fid.AxisConstants, figures: Mapping[str, float],
          engine: bool) -> dict[str, Any]:
    return {"axis": config.axis, "kp_dac_per_count": config.kp_dac_per_count,
            "gain_blu_s_per_dac": constants.gain_blu_s_per_dac,
            "encoder_counts_per_blu": constants.encoder_counts_per_blu,
            "speeds_mm_s": list(config.speeds_mm_s), "seeds": list(config.seeds),
            "settle_s": config.settle_s, "window_s": config.window_s, "ran_on": "engine" if engine else "node graph",
            "fitted_from": "nominal plant, steady speeds",
            "agreement": {k: round(v, 4) for k, v in figures.items() if math.isfinite(v)}}
