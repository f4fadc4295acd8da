"""Paper 000's published numbers (Tables 4 and 5, the two experiments) and the scenarios that reproduce them.

The paper's values are data: every paper-000 bench prints them beside ours.
Source: ``../shared/seeds/000_ae11d5324699fecb.txt`` (section 4), digest in
``../shared/spec/seeds.md``. Lengths in BLU (10 µm), as the paper's tables.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.laws.pid import pid_gains_from_per_sample

#: Table 4: the PID gains and the FLC's equivalent gains (per sample, at the paper's T).
TABLE4_GAINS: dict[str, float] = {"kp": 2.4, "ki": 0.1, "kd": 6.7}
#: The paper's sample time T [s], which Table 4's per-sample gains include.
TABLE4_SAMPLE_TIME_S = 0.01
#: Table 4 as the PID's time-unit gains (``kp`` 2.4, ``ki`` 10 /s, ``kd`` 0.067 s): what scenarios hold.
TABLE4_PID_PARAMS: dict[str, float] = pid_gains_from_per_sample(**TABLE4_GAINS, sample_time_s=TABLE4_SAMPLE_TIME_S)
#: Table 2: nominal open-loop gain K [BLU/s per DAC unit] and time constant τ [s] per axis.
TABLE2_AXES: dict[str, tuple[float, float]] = {"x": (28.35, 0.055), "y": (28.96, 0.056)}


@dataclass(frozen=True)
class Table5Row:
    """One row of Table 5: max and RMS contour error [BLU] of the PID and the FLC."""

    contour: str
    feed: str
    feed_m_min: float
    max_pid_blu: float
    max_flc_blu: float
    rms_pid_blu: float
    rms_flc_blu: float

    @property
    def case(self) -> str:
        """Case name, e.g. ``line_low``."""
        return f"{self.contour}_{self.feed}"

    @property
    def scenario(self) -> str:
        """The scenario file of this row, relative to the project root."""
        return f"scenarios/paper000_{self.case}.yaml"

    def paper_value(self, controller: str, metric: str) -> float:
        """The paper's ``metric`` (``max``/``rms``) for ``controller`` (``pid``/``flc``), BLU."""
        if controller not in ("pid", "flc") or metric not in ("max", "rms"):
            raise ConfigError(f"paper 000 reports pid/flc x max/rms, got {controller!r}/{metric!r}")
        return float(getattr(self, f"{metric}_{controller}_blu"))


#: Table 5 (simulation, unit 10 µm), in the paper's order.
TABLE5: tuple[Table5Row, ...] = (
    Table5Row("line", "low", 0.4, 9.3, 6.6, 1.8, 1.6),
    Table5Row("line", "high", 0.9, 9.4, 8.3, 1.9, 1.6),
    Table5Row("circle", "low", 0.4, 11.9, 10.0, 4.2, 2.7),
    Table5Row("circle", "high", 1.3, 39.9, 25.7, 27.7, 11.7),
    Table5Row("corner", "low", 0.3, 25.2, 17.4, 5.0, 3.2),
    Table5Row("corner", "high", 0.6, 46.0, 40.2, 7.8, 5.3),
)


@dataclass(frozen=True)
class Experiment:
    """One of the paper's machine experiments: how much the FLC cut the PID's error (PID:FLC).

    A ratio the paper does not state is ``None``.
    """

    name: str
    description: str
    scenario: str
    max_ratio_pid_to_flc: float | None
    rms_ratio_pid_to_flc: float | None


#: Section 4.2: the 3-axis mill (we simulate them on the paper-000 plant).
EXPERIMENTS: tuple[Experiment, ...] = (
    Experiment("line27", "line at 27° to X, 0.4 m/min (Fig. 12)", "scenarios/paper000_exp_line27.yaml", 2.1, None),
    Experiment("circle_1.0", "circle r = 20 mm, 1.0 m/min (Fig. 13)", "scenarios/paper000_exp_circle.yaml", 1.9, 3.5),
)


def table5_row(case: str) -> Table5Row:
    """The Table 5 row of ``case`` (e.g. ``circle_high``); an unknown case lists the valid ones."""
    rows = {row.case: row for row in TABLE5}
    if case not in rows:
        raise ConfigError(f"case must be one of {sorted(rows)}, got {case!r}")
    return rows[case]
