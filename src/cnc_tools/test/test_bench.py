"""Benches: the registry, the table helper, the ping-pong peers, and the engine's fast path.

No timing assertions: the benches measure, the tests check that what they
measure is the same computation.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from cnc_contour_control.axis.servo import ServoController
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.lockstep import NS_PER_S, ns_to_s, seconds_to_ns
from cnc_plant_sim.models.plant import make_plant
from cnc_tools.analysis.tables import format_table, write_json
from cnc_tools.bench.registry import BENCHES, get_bench
from cnc_tools.cli.main import main
from cnc_tools.runs.engine import run_engine, tick_count, tick_stamps_s
from cnc_tools.runs.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[3]
SHIPPED = sorted((ROOT / "scenarios").glob("*.yaml"))
SAMPLE_TIMES_S = (0.01, 0.001)


# ---------------------------------------------------------------- registry and output


def test_lockstep_bench_is_registered() -> None:
    assert get_bench("lockstep") is BENCHES["lockstep"]


def test_unknown_bench_lists_the_valid_names() -> None:
    with pytest.raises(ConfigError, match=r"bench must be one of \[.*'lockstep'.*\], got 'nope'"):
        get_bench("nope")


def test_cli_refuses_an_unknown_bench_listing_the_names(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "nope"]) == 2
    assert "'lockstep'" in capsys.readouterr().err


def test_table_aligns_numbers_right_and_text_left() -> None:
    lines = format_table(["name", "value"], [["a", 1.5], ["long name", 1234.0]], indent="").splitlines()
    assert lines == ["name       value", "a            1.5", "long name   1234"]


def test_json_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "figures.json"
    write_json(path, {"ratio": 1.5, "met": True})
    assert json.loads(path.read_text()) == {"ratio": 1.5, "met": True}


# ---------------------------------------------------------------- engine speed path


def scenario(path: Path, sample_time_s: float) -> Scenario:
    return load_scenario(path, {"sample_time_s": sample_time_s})


@pytest.mark.parametrize("sample_time_s", SAMPLE_TIMES_S)
@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_tick_stamps_are_the_wire_stamps_in_seconds(path: Path, sample_time_s: float) -> None:
    run = scenario(path, sample_time_s)
    n_ticks, sample_ns = tick_count(run), seconds_to_ns(run.sample_time_s)
    expected = [ns_to_s(k * sample_ns) for k in range(n_ticks)]
    assert tick_stamps_s(n_ticks, sample_ns).tolist() == expected


@pytest.mark.parametrize("sample_time_s", SAMPLE_TIMES_S)
@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_sample_array_equals_per_tick_sample(path: Path, sample_time_s: float) -> None:
    run = scenario(path, sample_time_s)
    interpolator = run.make_interpolator()
    times = tick_stamps_s(tick_count(run), seconds_to_ns(run.sample_time_s))
    many = interpolator.sample_array(times)
    each = [interpolator.sample(float(t)) for t in times]
    for name in ("position_m", "velocity_m_s", "acceleration_m_s2"):
        assert_allclose(getattr(many, name), np.array([getattr(s, name) for s in each]), rtol=0, atol=1e-12,
                        err_msg=name)


def per_tick_engine(run: Scenario) -> dict[str, np.ndarray]:
    """The node graph's computation written plainly: one interpolator.sample, servo.step, plant.step per tick."""
    plant = make_plant(run.plant)
    interpolator = run.make_interpolator()
    servos = [ServoController(config) for config in run.servos]
    plant.reset(list(run.program.start_m))
    sample_ns = seconds_to_ns(run.sample_time_s)
    rows: dict[str, list[np.ndarray]] = {"position": [], "velocity": [], "reference": [], "command": []}
    for k in range(tick_count(run)):
        positions, velocities = plant.positions_m(), plant.velocities_m_s()
        sample = interpolator.sample(ns_to_s(k * sample_ns))
        commands = [servo.step(sample_ns / NS_PER_S, float(sample.position_m[i]), float(sample.velocity_m_s[i]),
                               float(sample.acceleration_m_s2[i]), float(positions[i]), float(velocities[i]),
                               0.0).command
                    for i, servo in enumerate(servos)]
        plant.step(commands, run.sample_time_s)
        for key, value in zip(rows, (positions, velocities, sample.position_m, commands)):
            rows[key].append(np.asarray(value, dtype=float))
    return {key: np.array(value) for key, value in rows.items()}


@pytest.mark.parametrize(("name", "sample_time_s"), [
    ("paper000_circle_high", 0.01), ("paper000_circle_high", 0.001), ("paper000_corner_high", 0.01),
    ("paper000_circle_low", 0.01), ("helix_3axis", 0.01),
])
def test_engine_equals_the_per_tick_computation(name: str, sample_time_s: float) -> None:
    run = scenario(ROOT / "scenarios" / f"{name}.yaml", sample_time_s)
    fast, plain = run_engine(run), per_tick_engine(run)
    assert fast.ticks == plain["position"].shape[0]
    assert fast.reference is not None
    for got, key in ((fast.joint_states.position_m, "position"), (fast.joint_states.velocity_m_s, "velocity"),
                     (fast.reference.position_m, "reference"), (fast.command_array(), "command")):
        assert_allclose(got, plain[key], rtol=0, atol=1e-9, err_msg=key)


def test_servo_command_is_step_command() -> None:
    run = scenario(ROOT / "scenarios" / "paper000_circle_high.yaml", 0.01)
    fast, plain = ServoController(run.servos[0]), ServoController(run.servos[0])
    for k in range(300):
        args = (0.01, 1e-4 * np.sin(0.05 * k), 1e-3, 0.0, 1e-4 * np.sin(0.05 * k - 0.3), 1e-3, 0.0)
        assert fast.command(*args) == plain.step(*args).command


# ---------------------------------------------------------------- ping-pong peers (real rclpy)


@pytest.mark.nodes
@pytest.mark.parametrize("message", ["reference", "float64"])
def test_pingpong_peers_answer(tmp_path: Path, message: str) -> None:
    from cnc_tools.bench.peers import round_trips

    times = round_trips(tmp_path, message, iterations=20, warmup=5, timeout_s=60.0)
    assert len(times) == 20 and all(t > 0.0 for t in times)


@pytest.mark.nodes
def test_peers_stop_what_they_started(tmp_path: Path) -> None:
    from cnc_tools.bench.peers import PINGPONG, Peers

    with Peers(tmp_path) as peers:
        echo = peers.start("echo", PINGPONG, ["echo", "--ping", "/bench_test/ping", "--pong", "/bench_test/pong"])
    assert echo.poll() is not None


def test_sweep_bench_gives_the_same_results_in_every_configuration(capsys: pytest.CaptureFixture[str]) -> None:
    import argparse

    assert get_bench("sweep")(argparse.Namespace(quick=True, json=None)) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines()
            if line.strip().startswith(("1 process", "pool", "Dask")) and not line.rstrip().endswith("...")]
    assert len(rows) == 3 and all(row.rstrip().endswith("True") for row in rows), out
