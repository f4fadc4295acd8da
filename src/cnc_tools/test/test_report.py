"""PNG reports: files written, real PNGs of non-trivial content, runs side by side."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.analysis.report import FIGURES, nice_magnification, write_report
from cnc_tools.analysis.scoring import score_run
from cnc_tools.bagio.bag import read_bag

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
R_M = 0.02


def _assert_png(path: Path, min_bytes: int = 10_000) -> None:
    assert path.is_file(), path
    assert path.read_bytes()[:8] == PNG_MAGIC, f"{path} is not a PNG"
    assert path.stat().st_size >= min_bytes, f"{path} is only {path.stat().st_size} bytes"
    pixels = imread(path)
    assert pixels.shape[0] > 200 and pixels.shape[1] > 200
    assert np.std(pixels[..., :3]) > 0.02, f"{path} is blank"


@pytest.fixture(scope="module")
def circle_runs(circle_bag: Path, synth):
    lagging = synth.circle_trajectory(R_M, -4e-6, n=1500, lag_rad=0.01)
    return [read_bag(circle_bag), synth.make_run(synth.circle_program(), lagging, name="lagging")]


def test_all_figures_of_two_circle_runs(tmp_path: Path, circle_runs) -> None:
    written = write_report(circle_runs, tmp_path / "report")
    assert [p.name for p in written] == [name for name, _ in FIGURES.values()]
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == sorted(p.name for p in written)
    for path in written:
        _assert_png(path)


def test_side_by_side_panels_are_wider_than_one(tmp_path: Path, circle_runs) -> None:
    one = imread(write_report(circle_runs[:1], tmp_path / "one", figures=["xy"])[0])
    two = imread(write_report(circle_runs, tmp_path / "two", figures=["xy"])[0])
    assert two.shape[1] >= 1.8 * one.shape[1]


def test_without_a_circle_the_polar_plot_is_skipped(tmp_path: Path, synth) -> None:
    program = synth.corner_program()
    run = synth.make_run(program, synth.offset_trajectory(program, [3e-6, -2e-6]), name="corner")
    written = write_report([run], tmp_path)
    assert "circular_test.png" not in [p.name for p in written]
    assert len(written) == len(FIGURES) - 1
    for path in written:
        _assert_png(path)


def test_unknown_figure_and_bad_arguments_are_refused(tmp_path: Path, circle_runs) -> None:
    with pytest.raises(ConfigError, match=r"figures must be one of \['circular', 'error_path'"):
        write_report(circle_runs, tmp_path, figures=["spectrum"])
    with pytest.raises(ConfigError, match="magnification must be > 0"):
        write_report(circle_runs, tmp_path, magnification=-1.0)
    with pytest.raises(ConfigError, match="at least one"):
        write_report([], tmp_path)
    with pytest.raises(ConfigError, match="one entry per run"):
        write_report(circle_runs, tmp_path, scores=[score_run(circle_runs[0])])


def test_automatic_magnification_is_1_2_5_and_bounded(circle_runs) -> None:
    scores = [score_run(run) for run in circle_runs]
    factor = nice_magnification(circle_runs, scores)
    mantissa = factor / 10 ** np.floor(np.log10(factor))
    assert round(mantissa, 9) in (1.0, 2.0, 5.0)
    largest_m = max(float(s.series.error_m.max()) for s in scores)
    assert factor * largest_m <= 0.08 * 2 * R_M < 2.5 * factor * largest_m
