"""Paper 002's published numbers and the goals of issue 10 (data, printed beside ours).

Source: ``../shared/seeds/002_aecfba2eeb2aee0c.txt`` (section IV), digest in
``../shared/spec/seeds.md`` section 002.

- :data:`PAPER_RMS_PULSE`: the RMS position errors "at constant speed, where
  the periodic disturbance outweighs the friction", (a)-(f), in pulses
  (1 pulse = 1/2.4 µm), printed after Fig. 9 (the line). The text lists five
  methods (none, DOB, MBDA, DOB+PDC, MBDA+PDC) and six numbers; we read (a)
  as a reference run without the periodic disturbance and (b)-(f) as the five
  methods in turn (:data:`PAPER_READING`), the digest's reading: the other
  reading ((a)-(e) the methods) makes DOB+PDC remove 4 % against DOB, not the
  "about 80 %" of the text.
- :data:`REMOVAL_CLAIM`: "the error caused by the periodic disturbance is
  reduced by about 80 % by the PDC".
- :data:`W_X`, :data:`W_Y`, :data:`M_L`, :data:`D_L`: the PDC's design
  (section IV); f_d = 1500 rpm × 2 flutes / 60 = 50 Hz (Eq. 2).
- The contours: the line moves 2 mm on each of X and Y at 120 mm/min (we read a
  straight line to (2, 2) mm, 120 mm/min along the path); the circle has
  r = 6 mm at 120 mm/min; both with trapezoidal acceleration.
"""
from __future__ import annotations

import math

from cnc_contour_control.core.units import M_PER_PULSE_PAPER002

#: Section IV: RMS position error at constant speed [pulse], (a)-(f).
PAPER_RMS_PULSE: dict[str, float] = {"a": 0.1271, "b": 0.9406, "c": 1.5144, "d": 0.8987, "e": 0.2616, "f": 0.1802}
#: Our reading of (a)-(f): the run each letter belongs to (a law name, or "reference": no periodic disturbance).
PAPER_READING: dict[str, str] = {"a": "reference", "b": "p", "c": "dob", "d": "mbda", "e": "dob_pdc", "f": "mbda_pdc"}
#: Section IV: the share of the periodic disturbance's error the PDC removes ("about 80 %").
REMOVAL_CLAIM = 0.80
#: Section IV: W for the modified models of X and Y (3 taps, ascending powers of z⁻¹).
W_X: tuple[float, float, float] = (9.915, -21.856, 11.276)
W_Y: tuple[float, float, float] = (13.102, -29.523, 15.766)
#: Section IV: |L(f_d)| and L's delay [samples].
M_L = 0.7
D_L = 6
#: Section IV: the spindle, the tool and the disturbance frequency (Eq. 2).
SPINDLE_RPM = 1500.0
FLUTES = 2
F_D_HZ = SPINDLE_RPM * FLUTES / 60.0
#: Section IV: the contours.
FEED_MM_MIN = 120.0
LINE_TO_MM: tuple[float, float] = (2.0, 2.0)
CIRCLE_RADIUS_MM = 6.0
#: 1 pulse [m] (1/2.4 µm).
M_PER_PULSE = M_PER_PULSE_PAPER002

#: Issue 10's goals for our best stack.
GOAL_REMOVAL = 0.95
GOAL_PEAK = 2.0
GOAL_INERTIA_ERROR = 0.2
GOAL_SPINDLE_TOLERANCE = 0.05
GOAL_SPINDLE_REMOVAL = 0.90

#: The paper's pairs "method" -> "method + PDC" behind the 80 % claim.
PDC_PAIRS: tuple[tuple[str, str], ...] = (("dob", "dob_pdc"), ("mbda", "mbda_pdc"))


def paper_rms(run: str) -> float | None:
    """The paper's RMS [pulse] for a run of our reading (a law name or "reference"), None if it has none."""
    for letter, name in PAPER_READING.items():
        if name == run:
            return PAPER_RMS_PULSE[letter]
    return None


def paper_letter(run: str) -> str:
    """The paper's letter of a run ("-" if none)."""
    return next((f"({k})" for k, v in PAPER_READING.items() if v == run), "-")


def periodic_rms(rms: float, floor: float) -> float:
    """The part of ``rms`` not in ``floor`` (both RMS of one quantity): sqrt(rms² − floor²), 0 if below."""
    return math.sqrt(max(rms * rms - floor * floor, 0.0))


def paper_removals() -> dict[str, dict[str, float]]:
    """The PDC's share per pair, read two ways: plain RMS ratio, and with the reference (a) taken out in quadrature."""
    floor = PAPER_RMS_PULSE["a"]
    out = {}
    for base, with_pdc in PDC_PAIRS:
        before, after = paper_rms(base), paper_rms(with_pdc)
        assert before is not None and after is not None
        out[with_pdc] = {"plain": 1.0 - after / before,
                         "periodic": 1.0 - periodic_rms(after, floor) / periodic_rms(before, floor)}
    return out
