"""Paper 003's Table 2 and results beside what each reading of its open points gives.

Three checks, each a table of rows (plain dicts, so a bench or a doc prints them):

- :func:`radius_rows`: per lag reading and form, the grid objective of the
  standard and the optimal column and their ratio (paper: 135 → 90 µm, 0.667),
  first with ``T_ip = 0``, then with ``T_ip`` fitted so the standard column
  gives the paper's 135 µm (one number fitted to one; the optimal column is
  then a prediction, compared with 90 µm);
- :func:`rise_rows`: rise time under each definition (paper: 0.16 → 0.13 s),
  the position gain fitted so the standard column rises in 0.16 s;
- :func:`box_rows`: the analytic optimum found by DE in the box K1 ≤ 100,
  K2 ≤ 2.6 and in a ten times larger box, per lag reading: where it sits.
"""
from __future__ import annotations

from typing import Any

from scipy.optimize import brentq

from cnc_tools.tuning import paper003_model as p3
from cnc_tools.tuning.objectives import AnalyticObjective, constraint_values, model_at
from cnc_tools.tuning.problem import Constraint, DesignVariable
from cnc_tools.tuning.solve import solve

PAPER_OPT_UM = p3.PAPER003_TABLE["optimal"].radius_error_um
PAPER_STD_UM = p3.PAPER003_TABLE["standard"].radius_error_um
PAPER_RATIO = PAPER_OPT_UM / PAPER_STD_UM
#: The variables of the box check (paths of :data:`cnc_tools.tuning.objectives.ANALYTIC_PATHS`).
K1_PATH, K2_PATH = "plant.axis_overrides.*.ki", "plant.axis_overrides.*.kp"


def _columns(base: p3.Paper003Model, readings: p3.Readings) -> tuple[float, float]:
    return tuple(p3.objective_um(p3.model_of_column(c, base), readings) for c in ("standard", "optimal"))  # type: ignore[return-value]  # two columns


def _fit_t_ip(base: p3.Paper003Model, readings: p3.Readings) -> float | None:
    """T_ip [s] making the standard column's objective 135 µm; None when T_ip = 0 already exceeds it."""
    def gap(t_ip_s: float) -> float:
        return p3.objective_um(p3.model_of_column("standard", base.with_(t_ip_s=t_ip_s)), readings) - PAPER_STD_UM

    if gap(0.0) > 0.0:
        return None
    return float(brentq(gap, 0.0, 1.0, xtol=1e-9))


def radius_rows(base: p3.Paper003Model | None = None, aggregate: str = "mean") -> list[dict[str, Any]]:
    """Objective of both columns per lag reading and form, with T_ip = 0 and with T_ip fitted to 135 µm."""
    model = base or p3.Paper003Model()
    rows = []
    for lag in p3.LAG_READINGS:
        for form in p3.LAG_FORMS:
            readings = p3.Readings(lag=lag, lag_form=form, aggregate=aggregate)
            std, opt = _columns(model, readings)
            t_ip = _fit_t_ip(model, readings)
            fitted = _columns(model.with_(t_ip_s=t_ip), readings) if t_ip is not None else (None, None)
            rows.append({"lag": lag, "form": form, "std_um": std, "opt_um": opt,
                         "ratio": opt / std if std > 0 else None, "t_ip_fit_s": t_ip,
                         "std_fit_um": fitted[0], "opt_fit_um": fitted[1],
                         "paper_std_um": PAPER_STD_UM, "paper_opt_um": PAPER_OPT_UM})
    return rows


def loop_rows(gains_1_s: tuple[float, ...] = (13.5, 30.0, 60.0)) -> list[dict[str, Any]]:
    """The closed position loop's own radius reduction over the grid, both columns, per position gain."""
    rows = []
    for gain in gains_1_s:
        base = p3.Paper003Model(position_gain_x_1_s=gain, position_gain_y_1_s=gain)
        std, opt = (p3.loop_grid_error_um(p3.model_of_column(c, base)) for c in ("standard", "optimal"))
        rows.append({"position_gain_1_s": gain, "std_um": std, "opt_um": opt, "ratio": opt / std,
                     "paper_std_um": PAPER_STD_UM, "paper_opt_um": PAPER_OPT_UM})
    return rows


def rise_rows(base: p3.Paper003Model | None = None) -> list[dict[str, Any]]:
    """Rise times of both columns: velocity loop alone, and the position loop with k fitted to 0.16 s."""
    model = base or p3.Paper003Model()
    paper = {c: p3.PAPER003_TABLE[c].rise_time_s for c in ("standard", "optimal")}

    def position_rise(column: str, gain: float) -> float:
        m = p3.model_of_column(column, model.with_(position_gain_x_1_s=gain, position_gain_y_1_s=gain))
        return p3.rise_time_position_loop_s(m)

    gain = float(brentq(lambda k: position_rise("standard", k) - paper["standard"], 1.0, 200.0, xtol=1e-6))
    return [
        {"definition": "velocity loop (Eq. 1) 10-90 %", "position_gain_1_s": None,
         **{f"{c}_s": p3.rise_time_velocity_loop_s(p3.model_of_column(c, model)) for c in paper}},
        {"definition": "position loop 10-90 %, k fitted to 0.16 s", "position_gain_1_s": gain,
         **{f"{c}_s": position_rise(c, gain) for c in paper}},
        {"definition": "Eq. 16 (torque-limited, no K1, K2)", "position_gain_1_s": None,
         "standard_s": None, "optimal_s": None},
    ]


#: Eq. 15 read literally (``M_p <= M_p*``) with ``M_p*`` at the optimal column's ζ = 1.63: an upper bound on ζ.
EQ15_AT_OPTIMAL = Constraint("phase_margin_eq15_deg", "<=", round(p3.phase_margin_eq15_deg(1.63), 2))


def _box_row(lag: str, scale: float, constraints: tuple[Constraint, ...], maxiter: int, seed: int
             ) -> dict[str, Any]:
    """The DE optimum of one lag reading in the box scaled by ``scale``, and which bounds it touches."""
    variables = (DesignVariable(K1_PATH, 1.0, 100.0 * scale), DesignVariable(K2_PATH, 0.05, 2.6 * scale))
    objective = AnalyticObjective({}, variables, p3.Readings(lag=lag, lag_form="first_order_radius"))
    result = solve(objective, variables, constraints,
                   lambda x: constraint_values(model_at({}, variables, x), constraints),
                   maxiter=maxiter, popsize=10, seed=seed, unit="um")
    at_edge = [name for name, v, x in zip(("K1", "K2"), variables, result.x, strict=True)
               if min(x - v.low, v.high - x) <= 0.01 * (v.high - v.low)]
    model = model_at({}, variables, result.x)
    return {"lag": lag, "box": f"K1<={100 * scale:g}, K2<={2.6 * scale:g}",
            "constraints": ", ".join(map(str, constraints)) or "-", "k1": result.x[0], "k2": result.x[1],
            "zeta": model.zeta, "omega_n_rad_s": model.omega_n_rad_s, "objective_um": result.objective,
            "at_edge": ",".join(at_edge) or "-", "feasible": result.feasible}


def box_rows(maxiter: int = 40, seed: int = 1) -> list[dict[str, Any]]:
    """The analytic optimum in the box K1 <= 100, K2 <= 2.6 and in one ten times larger, per lag reading.

    The last two rows add Eq. 15 read as written (an upper bound on M_p, so on ζ)
    at the optimal column's ζ: under the envelope reading the objective falls
    with K2 alone, K2 stops at the box, and ζ <= 1.63 then forces K1 >= c K2² / (4 · 1.63²).
    """
    rows = [_box_row(lag, scale, (), maxiter, seed)
            for lag in ("envelope", "natural", "slowest_pole") for scale in (1.0, 10.0)]
    rows += [_box_row("envelope", scale, (EQ15_AT_OPTIMAL,), maxiter, seed) for scale in (1.0, 10.0)]
    return rows


def _cells(row: dict[str, Any], keys: tuple[str, ...]) -> list[object]:
    return ["-" if row[k] is None else (round(row[k], 4) if isinstance(row[k], float) else row[k]) for k in keys]


def readings_tables() -> str:
    """The three checks as aligned tables, the paper's numbers beside ours."""
    from cnc_tools.analysis.tables import format_table

    radius_keys = ("lag", "form", "std_um", "opt_um", "ratio", "t_ip_fit_s", "std_fit_um", "opt_fit_um")
    loop_keys = ("position_gain_1_s", "std_um", "opt_um", "ratio")
    rise_keys = ("definition", "position_gain_1_s", "standard_s", "optimal_s")
    box_keys = ("lag", "box", "constraints", "k1", "k2", "zeta", "omega_n_rad_s", "objective_um", "at_edge")
    paper = p3.PAPER003_TABLE
    return "\n".join([
        f"radius error, mean over the grid [um] (paper: {PAPER_STD_UM:g} -> {PAPER_OPT_UM:g}, ratio {PAPER_RATIO:.3f})",
        format_table(radius_keys, [_cells(r, radius_keys) for r in radius_rows()]),
        "the closed position loop's own radius reduction R (1 - |T(jw)|), mean over the grid [um]",
        format_table(loop_keys, [_cells(r, loop_keys) for r in loop_rows()]),
        f"rise time to a feed step [s] (paper: {paper['standard'].rise_time_s:g} -> {paper['optimal'].rise_time_s:g})",
        format_table(rise_keys, [_cells(r, rise_keys) for r in rise_rows()]),
        f"analytic optimum per box (paper: K1 {paper['optimal'].k1:g}, K2 {paper['optimal'].k2:g}, "
        f"zeta {paper['optimal'].zeta:g}, omega_n {paper['optimal'].omega_n_rad_s:g})",
        format_table(box_keys, [_cells(r, box_keys) for r in box_rows()]),
    ])
