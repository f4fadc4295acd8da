"""Equivalent PID gains of the FLC of paper 000 (Eqs. 11-13, Table 4).

The paper splits the FLC output into a part due to the error and a part due
to its change, ``u_F = u_1 + u_2`` with ``u_1 = phi_1[e]`` and
``u_2 = phi_2[de]`` (Eqs. 11, 12), bounds each part by a sector,
``K1_min e^2 <= u_1 e <= K1_max e^2`` and ``K2_min de^2 <= u_2 de <= K2_max de^2``
(Eq. 13), and takes the middle of each sector as the equivalent gain:
``K_P = (K1_min + K1_max) / 2`` and, since ``K2_min = 0`` for its rule base,
``K_D = K2_max / 2``.

The paper does not say where the sectors are evaluated. We take
``u_1 = F[e, 0]`` and ``u_2 = F[e, de] - F[e, 0]`` on the rule grid (every
pair of centres), where ``F`` equals the rule's output centre exactly. With
Table 3 and the reconstructed Table 1 this gives K_P = 2.38 and K_D = 6.67,
which round to Table 4's 2.4 and 6.7. (Bounds over the continuous plane would
give K2 in about [-13, 26], because Mamdani min inference bends ``F`` in thin
strips next to the grid lines; the paper's K2_min = 0 rules that reading out.)
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from cnc_contour_control.laws.fuzzy import RULE_BASES, FuzzyConfig, FuzzySurface

#: Table 4 of paper 000: the PID gains, also used as the FLC's equivalent gains.
TABLE4_GAINS: dict[str, float] = {"kp": 2.4, "ki": 0.1, "kd": 6.7}


@dataclasses.dataclass(frozen=True)
class EquivalentGains:
    """Sector bounds (Eq. 13) and equivalent gains of an FLC.

    All gains are in DAC per BLU (``kd``: DAC per BLU of change per sample;
    ``ki``: DAC per BLU per sample), the units of the incremental PID, Eq. 14.
    """

    k1_min: float
    k1_max: float
    k2_min: float
    k2_max: float
    ki: float

    @property
    def kp(self) -> float:
        """Equivalent proportional gain, the middle of the K1 sector."""
        return 0.5 * (self.k1_min + self.k1_max)

    @property
    def kd(self) -> float:
        """Equivalent derivative gain, the middle of the K2 sector (K2_max / 2 if K2_min = 0)."""
        return 0.5 * (self.k2_min + self.k2_max)


def sector_slopes(config: FuzzyConfig) -> tuple[list[float], list[float]]:
    """Return the slopes ``u_1/e`` and ``u_2/de`` at every grid point of ``config``.

    Parameters
    ----------
    config : FuzzyConfig
        The FLC; its scales are included (slopes refer to unscaled e, de in BLU).

    Returns
    -------
    k1 : list of float
        ``u_scale * F[e_i, 0] / e_i`` for every error centre ``e_i != 0`` (DAC/BLU).
    k2 : list of float
        ``u_scale * (F[e_i, de_j] - F[e_i, 0]) / de_j`` for every pair with ``de_j != 0``.
    """
    u = FuzzySurface(config)
    # ``+ 0.0`` turns the -0.0 of a flat rule row into 0.0 for printing.
    k1 = [u(e, 0.0) / e + 0.0 for e in u.e_points if e != 0.0]
    k2 = [(u(e, de) - u(e, 0.0)) / de + 0.0 for e in u.e_points for de in u.de_points if de != 0.0]
    return k1, k2


def equivalent_gains(config: FuzzyConfig) -> EquivalentGains:
    """Return the sector bounds and equivalent P, I, D gains of ``config`` (Eqs. 11-13)."""
    k1, k2 = sector_slopes(config)
    return EquivalentGains(min(k1), max(k1), min(k2), max(k2), config.ki)


def format_gains_table(names: Sequence[str] | None = None) -> str:
    """Return a text table of the equivalent gains of the named rule bases beside Table 4.

    ``names`` are keys of ``RULE_BASES`` (default: all), with Table 3's centres.
    """
    names = list(names or RULE_BASES)
    paper = TABLE4_GAINS
    lines = [
        "Equivalent FLC gains (paper 000, Eqs. 11-13) with Table 3 centres",
        f"{'rule base':16s} {'P':>6s} {'I':>6s} {'D':>6s}   K1 sector        K2 sector",
        f"{'Table 4 (paper)':16s} {paper['kp']:6.2f} {paper['ki']:6.2f} {paper['kd']:6.2f}",
    ]
    for name in names:
        g = equivalent_gains(FuzzyConfig(rule_base=name))
        lines.append(
            f"{name:16s} {g.kp:6.2f} {g.ki:6.2f} {g.kd:6.2f}   "
            f"[{g.k1_min:5.2f}, {g.k1_max:5.2f}]   [{g.k2_min:5.2f}, {g.k2_max:5.2f}]"
        )
    return "\n".join(lines)
