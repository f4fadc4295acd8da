"""The paper-002 bench's figures (png): error traces (Figs. 9-10 kind), frequency responses (Figs. 7-8 kind),
the disturbance responses of the five methods, the f_d sweep and the spindle step. matplotlib loads on use."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.disturbance.loop import closed_loop, frequency_grid_hz, responses
from cnc_contour_control.laws.disturbance import PdcConfig, PositionLoopConfig
from cnc_contour_control.laws.loop_report import loop_blocks, pdc_frequency_responses
from cnc_tools.reproductions.paper002.runs import METHODS, Result

#: Half-width of the zoomed trace windows [s].
ZOOM_S = 0.05


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(figure: Any, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    _pyplot().close(figure)
    return path


def _label(key: str) -> str:
    """A trace's label from its case key."""
    return "reference (no periodic)" if key.endswith("/ref") else METHODS[key.split("/")[1]]


def plot_traces(results: Mapping[str, Result], keys: Sequence[str], title: str, path: Path) -> Path:
    """Signed contour error [pulse] of each run over time, and a 0.1 s zoom in the middle of its window."""
    plt = _pyplot()
    figure, axes = plt.subplots(len(keys), 2, figsize=(12, 1.6 * len(keys)), sharex="col", sharey=True,
                                gridspec_kw={"width_ratios": [3, 1]})
    for row, key in zip(axes, keys):
        found = results[key]
        t, e = found.trace_t_s, found.trace_pulse
        assert t is not None and e is not None, f"{key}: plot_traces takes runs kept with their trace"
        middle = 0.5 * sum(found.measure.window_s)
        zoom = (t > middle - ZOOM_S) & (t < middle + ZOOM_S)
        row[0].plot(t, e, linewidth=0.5)
        row[1].plot(t[zoom], e[zoom], linewidth=0.8)
        row[0].set_ylabel(f"{_label(key)}\n[pulse]", fontsize=8)
        row[0].set_ylim(-4, 4)
    axes[-1][0].set_xlabel("t [s]")
    axes[-1][1].set_xlabel("t [s] (zoom)")
    figure.suptitle(title)
    return _save(figure, path)


def plot_pdc_design(config: PdcConfig, path: Path, points: int) -> Path:
    """Figs. 7-8: |.| and phase of P_n, P_m, L (Fig. 7) and of W, H, H·P_n (Fig. 8), f_d marked."""
    plt = _pyplot()
    found = pdc_frequency_responses(config, points)
    f = found["f_hz"]
    figure, axes = plt.subplots(2, 2, figsize=(12, 7), sharex=True)
    for column, names in enumerate((("pn", "pm", "l"), ("w", "h", "hp"))):
        for name in names:
            axes[0][column].semilogx(f, 20 * np.log10(np.abs(found[name])), label=name)
            axes[1][column].semilogx(f, np.degrees(np.unwrap(np.angle(found[name]))), label=name)
        for ax in axes[:, column]:
            ax.axvline(config.f_d_hz(), color="grey", linestyle=":")
            ax.legend(fontsize=8)
        axes[0][column].set_ylabel("dB")
        axes[1][column].set_ylabel("deg")
        axes[1][column].set_xlabel("f [Hz]")
    axes[0][0].set_title("Fig. 7 kind: P_n, P_m = M_L z^-D_L P_n, L")
    axes[0][1].set_title("Fig. 8 kind: W, H = L W, H P_n (1 at f_d)")
    return _save(figure, path)


def plot_disturbance_responses(configs: Mapping[str, PositionLoopConfig], f_d_hz: float, path: Path,
                               points: int) -> Path:
    """|x/d| of each law (position per input disturbance, nominal plant) and its ratio to the P loop's."""
    plt = _pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for name, config in configs.items():
        f = frequency_grid_hz(config.nominal().sample_time_s, points)
        with_path = responses(closed_loop(loop_blocks(config)), f)[0, 1]
        bare = responses(closed_loop(loop_blocks(PositionLoopConfig(kp=config.kp, model=config.model))), f)[0, 1]
        axes[0].loglog(f, np.abs(with_path), label=name)
        axes[1].semilogx(f, 20 * np.log10(np.abs(with_path / bare)), label=name)
    axes[1].axhline(20 * np.log10(2.0), color="red", linestyle="--", linewidth=0.8, label="+6 dB")
    for ax in axes:
        ax.axvline(f_d_hz, color="grey", linestyle=":")
        ax.set_xlabel("f [Hz]")
        ax.legend(fontsize=8)
    axes[0].set_ylabel("|x/d| [counts per count/s]")
    axes[1].set_ylabel("|x/d| / P loop's [dB]")
    figure.suptitle("disturbance at the plant input to position, X axis, K_pp 40/s")
    return _save(figure, path)


def plot_sweep(rows: Sequence[Mapping[str, Any]], predictions: Mapping[str, Mapping[float, Mapping[str, Any]]],
               path: Path) -> Path:
    """Removal of the f_d line against f_d: measured (marks) and the design's (lines); the design's peaks."""
    plt = _pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for law, per_f in predictions.items():
        good = [(f, fig) for f, fig in sorted(per_f.items()) if fig is not None and "error" not in fig]
        line = axes[0].plot([f for f, _ in good], [100 * fig["removal_at_fd"] for _, fig in good], label=METHODS[law])
        measured = [(r["f_d_hz"], r["removal"].get(law)) for r in rows if r["removal"].get(law) is not None]
        axes[0].plot([f for f, _ in measured], [100 * v for _, v in measured], "o", color=line[0].get_color())
        axes[1].semilogy([f for f, _ in good], [fig["disturbance_peak"] for _, fig in good], label=METHODS[law])
    axes[0].set_ylim(-50, 105)
    axes[0].set_ylabel("f_d line removed [%] (marks: engine, lines: design)")
    axes[1].axhline(2.0, color="red", linestyle="--", linewidth=0.8)
    axes[1].set_ylabel("disturbance peak (max |x/d| / P loop's)")
    for ax in axes:
        ax.set_xlabel("f_d [Hz]")
        ax.legend(fontsize=8)
    return _save(figure, path)
