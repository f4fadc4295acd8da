"""Paper 003's published numbers, and where each comes from.

Source: ``../shared/seeds/003_10d1a386b6698ed9.txt``; digest in
``../shared/spec/seeds.md`` section 003. One declaration: Table 2 and the two
results live in :data:`cnc_tools.tuning.paper003_model.PAPER003_TABLE` (the
tuner uses them too) and the circular-test grid in its ``GRID_*`` constants;
this module names them for the bench and adds what the text says around them.

- Table 2 ("Parameter list"): ζ 0.71 → 1.63, ω_n 126 → 125 rad/s, K1 101.121 →
  99.522 [Nm/rad], K2 1.1396 → 2.596 [Nm·s/rad], standard → optimal.
- Sect. 4, Fig. 4: ramp position inputs at 1000, 5000 and 12000 mm/min; the rise
  time "up to a feed of 1000 mm/min" is about 0.16 s (standard) and about
  0.13 s (optimal), "about 18 % better". How it is measured (10-90 %, 0-100 %,
  on the velocity or the position) is not said.
- Sect. 4, Fig. 6: circular-interpolation *experiments on the machine tool*
  at 1000, 4000, 8000 mm/min, radii 1.5, 3, 5, 10 mm, each CW and CCW; the
  radius-reduction error was "about 135 µm" (standard) and "about 90 µm"
  (optimal), "about 30 % smaller". Whether that is one test of the grid, the
  largest or an average over it is not said; Fig. 6 is one plot.
- Not given: the position-loop gain k, T_ip and the kind of acceleration/
  deceleration, the sample time, the GA's bounds and the constraint bounds
  M_p*, T_r*.
"""
from __future__ import annotations

from cnc_tools.tuning.paper003_model import (
    GRID_DIRECTIONS,
    GRID_FEEDS_MM_MIN,
    GRID_RADII_MM,
    PAPER003_TABLE,
    RISE_FEED_MM_MIN,
    PaperColumn,
)

__all__ = ["COLUMNS", "GRID_DIRECTIONS", "GRID_FEEDS_MM_MIN", "GRID_RADII_MM", "PAPER003_TABLE", "PaperColumn",
           "RAMP_FEEDS_MM_MIN", "RISE_FEED_MM_MIN", "paper_ratio"]

#: Table 2's columns, in print order.
COLUMNS: tuple[str, ...] = ("standard", "optimal")
#: Sect. 4: the feeds of the ramp-input tests [mm/min] (the rise time is quoted at the first).
RAMP_FEEDS_MM_MIN: tuple[float, ...] = (1000.0, 5000.0, 12000.0)


def paper_ratio(field: str) -> float:
    """Optimal over standard of one :class:`PaperColumn` field (radius_error_um: 0.667, rise_time_s: 0.8125)."""
    return float(getattr(PAPER003_TABLE["optimal"], field) / getattr(PAPER003_TABLE["standard"], field))
