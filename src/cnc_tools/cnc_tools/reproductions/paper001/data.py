"""Paper 001's published numbers: Table 1 (plant and controller), Tables 2 and 3 (contour errors).

The paper's values are data: every paper-001 bench prints them beside ours.
Source: ``../shared/seeds/001_eeed07fb2ab162ee.txt`` (section 3, "모의실험 및
검토"); digest in ``../shared/spec/seeds.md`` section 001.

- :data:`TABLE1_AXES`: Table 1, columns m, B, f_c, f_s, α of the X and Y rows
  (the extracted table is garbled; this is the digest's consistent reading).
  No units are printed. Eqs. 18-19 are the model they belong to.
- :data:`TABLE1_PID`: Table 1, column "P/I/D 이득" (gains), ``5/20/0.01``, one
  set for both axes. Whether the gains are continuous-time or per sample, and
  per which length unit, is not printed (see ``readings.py``).
- :data:`TABLE1_NETWORK` and :data:`SAMPLE_TIME_S`: Table 1, "입력/은닉 노드수"
  (input/hidden nodes) ``8/5`` and "샘플링 시간" (sample time) ``1ms``;
  η = 0.05 and momentum 0.15 are in the text beside Eq. 20.
- :data:`TABLE2` (line at 45° to +X, 2.7 m/min) and :data:`TABLE3` (circle,
  r = 10 mm, 5 m/min): ε_peak, printed in mm, and ε_ISE, defined in the text
  as "실제 윤곽오차의 제곱의 합" (the sum of the squared actual contour
  errors) and labelled "(mm)" in Table 2; its unit and sample time are not
  stated (we compare it as Σε² in mm² over the 1 ms samples; ``readings.py``
  checks what that implies).
- :data:`FEEDS_M_MIN`, :data:`CIRCLE_RADIUS_MM`, :data:`LINE_ANGLE_DEG`: the text
  of section 3. The line's length and the circle's start are not stated.
"""
from __future__ import annotations

from dataclasses import dataclass

from cnc_contour_control.core.errors import ConfigError

#: Table 1, per axis: m, B, f_c, f_s, α (units not stated).
TABLE1_AXES: dict[str, dict[str, float]] = {
    "x": {"m": 0.45, "B": 0.01, "f_c": 3.0, "f_s": 1.0, "alpha": 2.0},
    "y": {"m": 0.65, "B": 0.01, "f_c": 4.0, "f_s": 1.5, "alpha": 2.0},
}
#: Table 1: the PID gains P/I/D of both axes (units and time base not stated).
TABLE1_PID: dict[str, float] = {"kp": 5.0, "ki": 20.0, "kd": 0.01}
#: Table 1: network inputs / hidden units; the text: learning rate and momentum.
TABLE1_NETWORK: dict[str, float] = {"inputs": 8, "hidden": 5, "learning_rate": 0.05, "momentum": 0.15}
#: Table 1: the sample time, s.
SAMPLE_TIME_S = 1.0e-3
#: Section 3: feeds of the two contours, m/min.
FEEDS_M_MIN: dict[str, float] = {"line": 2.7, "circle": 5.0}
#: Section 3: the circle's radius, mm, and the line's angle to +X, deg.
CIRCLE_RADIUS_MM = 10.0
LINE_ANGLE_DEG = 45.0


@dataclass(frozen=True)
class ContourResult:
    """One column of Table 2 or 3: a controller after some runs, ε_peak [mm] and ε_ISE (as printed)."""

    controller: str
    runs: int
    peak_mm: float
    ise: float


#: Table 2 (line, 45°, 2.7 m/min): PID, PID+NN after 10 and after 50 iterations (runs).
TABLE2: tuple[ContourResult, ...] = (
    ContourResult("pid", 0, 0.0961, 3.3009),
    ContourResult("pid+nn", 10, 0.0767, 2.3005),
    ContourResult("pid+nn", 50, 0.0321, 1.2825),
)
#: Table 3 (circle, r = 10 mm, 5 m/min): PID, PID+NN after 10 and after 50 iterations (runs).
TABLE3: tuple[ContourResult, ...] = (
    ContourResult("pid", 0, 0.0724, 17.8285),
    ContourResult("pid+nn", 10, 0.0445, 7.4691),
    ContourResult("pid+nn", 50, 0.0373, 5.1139),
)
#: The tables by contour.
TABLES: dict[str, tuple[ContourResult, ...]] = {"line": TABLE2, "circle": TABLE3}
#: The scenario of each contour, relative to the project root.
SCENARIOS: dict[str, str] = {"line": "scenarios/paper001_line.yaml", "circle": "scenarios/paper001_circle.yaml"}


def paper_result(contour: str, controller: str = "pid", runs: int = 0) -> ContourResult:
    """The paper's column for ``contour`` (line/circle), ``controller`` (pid/pid+nn) after ``runs`` runs."""
    if contour not in TABLES:
        raise ConfigError(f"contour must be one of {sorted(TABLES)}, got {contour!r}")
    for result in TABLES[contour]:
        if (result.controller, result.runs) == (controller, runs):
            return result
    valid = [(r.controller, r.runs) for r in TABLES[contour]]
    raise ConfigError(f"paper 001 reports {valid} for the {contour}, got {(controller, runs)!r}")
