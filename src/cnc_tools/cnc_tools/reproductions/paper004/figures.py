"""Force and override traces like the paper's Figs. 1, 2, 4, 5 (matplotlib loaded only here, when plotting)."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from cnc_tools.reproductions.paper004 import data
from cnc_tools.reproductions.paper004.runs import Result


def write_figure(path: Path, title: str, results: Sequence[Result]) -> Path:
    """One png: the force of every result (top, with the ±5 % band) and its applied override (bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (force_ax, ratio_ax) = plt.subplots(2, 1, sharex=True, figsize=(9, 6))
    band = data.BAND_FRACTION * data.REFERENCE_N
    force_ax.axhspan(data.REFERENCE_N - band, data.REFERENCE_N + band, color="0.9", label="±5 %")
    for result in results:
        force_ax.plot(result.traces.t_s, result.traces.force_n, lw=0.8, label=result.case.label)
        ratio_ax.step(result.traces.t_s, 100.0 * result.traces.applied_ratio, lw=0.8, where="post")
    force_ax.set_ylabel("cutting force [N]")
    ratio_ax.set_ylabel("applied override [%]")
    ratio_ax.set_xlabel("time [s]")
    force_ax.set_title(title)
    force_ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
