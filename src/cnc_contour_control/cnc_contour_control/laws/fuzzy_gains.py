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
pair of centres), where ``F`` equals the rule's output centre exactly. The
law's ``de`` is an error rate, so ``K_D`` comes out in seconds and ``K_I`` per
second; :meth:`EquivalentGains.per_sample` gives the paper's per-sample units.
With Table 3 and the reconstructed Table 1 this gives K_P = 2.38 and, per
sample at T = 10 ms, K_D = 6.67, which round to Table 4's 2.4 and 6.7. (Bounds over the continuous plane would
give K2 in about [-13, 26], because Mamdani min inference bends ``F`` in thin
strips next to the grid lines; the paper's K2_min = 0 rules that reading out.)
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from cnc_contour_control.laws.fuzzy import PAPER000_SAMPLE_TIME_S, RULE_BASES, FuzzyConfig, FuzzySurface
from cnc_contour_control.laws.pid import pid_gains_per_sample

#: Table 4 of paper 000: the PID gains, also used as the FLC's equivalent gains (per sample, T = 10 ms).
TABLE4_GAINS: dict[str, float] = {"kp": 2.4, "ki": 0.1, "kd": 6.7}


@dataclasses.dataclass(frozen=True)
class EquivalentGains:
    """Sector bounds (Eq. 13) and equivalent gains of an FLC.

    Gains in the PID's time units (:class:`~cnc_contour_control.laws.pid.PidConfig`):
    ``kp``, ``k1_*`` in drive units per count; ``kd``, ``k2_*`` in drive units
    per count/s; ``ki`` in drive units per count-second.
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

    def per_sample(self, sample_time_s: float = PAPER000_SAMPLE_TIME_S) -> dict[str, float]:
        """The equivalent gains as Eq. (14)'s per-sample ``kp``, ``ki``, ``kd`` (Table 4's units)."""
        return pid_gains_per_sample(self.kp, self.ki, self.kd, sample_time_s)


def sector_slopes(config: FuzzyConfig) -> tuple[list[float], list[float]]:
    """Return the slopes ``u_1/e`` and ``u_2/de`` at every grid point of ``config``.

    Parameters
    ----------
    config : FuzzyConfig
        The FLC; its scales are included (slopes refer to unscaled e, de in BLU).

    Returns
    -------
    k1 : list of float
        ``u_scale * F[e_i, 0] / e_i`` for every error centre ``e_i != 0`` (drive units per count).
    k2 : list of float
        ``u_scale * (F[e_i, de_j] - F[e_i, 0]) / de_j`` for every pair with ``de_j != 0``
        (drive units per count/s).
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
    Gains and the K2 sector are per sample at the paper's T = 10 ms, as Table 4.
    """
    names = list(names or RULE_BASES)
    paper, period = TABLE4_GAINS, PAPER000_SAMPLE_TIME_S
    lines = [
        "Equivalent FLC gains (paper 000, Eqs. 11-13) with Table 3 centres, per sample at T = 10 ms",
        f"{'rule base':16s} {'P':>6s} {'I':>6s} {'D':>6s}   K1 sector        K2 sector",
        f"{'Table 4 (paper)':16s} {paper['kp']:6.2f} {paper['ki']:6.2f} {paper['kd']:6.2f}",
    ]
    for name in names:
        g = equivalent_gains(FuzzyConfig(rule_base=name))
        p = g.per_sample(period)
        lines.append(
            f"{name:16s} {p['kp']:6.2f} {p['ki']:6.2f} {p['kd']:6.2f}   "
            f"[{g.k1_min:5.2f}, {g.k1_max:5.2f}]   [{g.k2_min / period:5.2f}, {g.k2_max / period:5.2f}]"
        )
    return "\n".join(lines)
