"""Bad scenario and program files give one ``error:`` line, never a traceback; ``check`` takes what the nodes take."""
from __future__ import annotations

import copy
import os
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

from cnc_contour_control.core.config import MAX_INPUT_FILE_BYTES
from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.params import param_specs
from cnc_contour_control.motion.program_file import read_program_file
from cnc_plant_sim.run.run_params import PlantRunParams
from cnc_tools.cli.main import main
from cnc_tools.runs.scenario import build_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
CIRCLE = SCENARIOS / "paper000_circle_high.yaml"


def _check(path: Path, capsys: pytest.CaptureFixture) -> str:
    """``cnc-contour check path``: exit code 2 and exactly one error line, returned."""
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("cnc-contour check: error: "), err
    return err


def _scenario(tmp_path: Path, **changes: Any) -> Path:
    raw = yaml.safe_load(CIRCLE.read_text())
    for dotted, value in changes.items():
        *parents, leaf = dotted.split("__")
        node = raw
        for key in parents:
            node = node[key]
        node[leaf] = value
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.mark.parametrize(("changes", "message"), [
    ({"seed": "abc"}, "scenario.seed must be an integer >= 0, got 'abc'"),
    ({"plant": 5}, "scenario.plant must be a mapping, got 5"),
    ({"servo__axes": ["x"]}, "scenario.servo.axes must map axis names to mappings"),
    ({"interpolator": [1]}, "scenario.interpolator must be a mapping"),
    ({"sample_time_s": 5}, "scenario.sample_time_s must be in [1e-05, 1.0], got 5"),
    ({"duration_s": 2e6}, "scenario.duration_s must be in [0.001, 1000000.0]"),
    # the key the user wrote, not the duration computed from it (issue 22)
    ({"settle_s": 1e300}, "scenario.settle_s must be in [0.0, 1000000.0], got 1e+300"),
    ({"limits__max_velocity_mm_min": 1e-7}, "scenario.limits.max_velocity_mm_min must be >= 0.01 mm/min, got 1e-07"),
    ({"limits__max_acceleration_mm_s2": 1e-300},
     "scenario.limits.max_acceleration_mm_s2 must be >= 0.001 mm/s^2, got 1e-300"),
    ({"program__radius_mm": 1e300}, "program.radius_mm must be in [0.001, 100000] mm, got 1e+300"),
    ({"program__feed_mm_min": 1e-7}, "program.feed_mm_min must be >= 0.01 mm/min, got 1e-07"),
    ({"program__radius_mm": True}, "program.radius_mm must be a number, got True"),
])
def test_bad_values_give_one_line(tmp_path: Path, capsys: pytest.CaptureFixture, changes: dict, message: str) -> None:
    assert message in _check(_scenario(tmp_path, **changes), capsys)


def test_the_sample_time_bound_is_the_plant_nodes_declared_range(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``sample_time_s: 5`` passed ``check`` and then died in rclpy: the bound is now the node's one declaration."""
    (spec,) = [s for s in param_specs(PlantRunParams) if s.name == "sample_time_s"]
    assert f"must be in [{spec.info.low}, {spec.info.high}]" in _check(
        _scenario(tmp_path, sample_time_s=spec.info.high * 1.5), capsys)
    assert main(["check", str(_scenario(tmp_path, sample_time_s=spec.info.high, duration_s=3.0))]) == 0


def test_a_binary_scenario_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "noise.yaml"
    path.write_bytes(bytes(range(256)) * 8)
    assert "is not a text file" in _check(path, capsys)
    path.write_bytes(b"name: x\x00\x00\n")
    assert "NUL character" in _check(path, capsys)


def test_a_binary_gcode_file(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    gcode = tmp_path / "part.ngc"
    gcode.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
    assert "program.gcode_file" in _check(_scenario(tmp_path, program={"gcode_file": "part.ngc"}), capsys)
    with pytest.raises(CncError, match="is not a text file"):
        read_program_file(gcode, ("x", "y"))


@pytest.mark.parametrize("kind", ["scenario", "gcode"])
def test_files_above_the_size_limit_are_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture,
                                                        kind: str) -> None:
    """A 50 MB scenario used to take ``check`` to 2.8 GB; now any file above the limit is refused unread."""
    big = tmp_path / ("big.yaml" if kind == "scenario" else "big.ngc")
    with open(big, "wb") as stream:
        stream.write(b"# padding\n")
        stream.truncate(MAX_INPUT_FILE_BYTES + 1)  # sparse: the size is what counts
    path = big if kind == "scenario" else _scenario(tmp_path, program={"gcode_file": big.name})
    started = time.monotonic()
    err = _check(path, capsys)
    assert time.monotonic() - started < 5.0
    assert f"{MAX_INPUT_FILE_BYTES + 1} bytes; the limit is {MAX_INPUT_FILE_BYTES} bytes (4 MiB)" in err


BAD_VALUES = [5, "abc", [1], ["x"], {"a": 1}, None, True, -1, 1e308, float("nan"), "", 0, [], {}]


def _paths(mapping: dict, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    out = []
    for key, value in mapping.items():
        out.append((*prefix, key))
        if isinstance(value, dict):
            out += _paths(value, (*prefix, key))
    return out


@pytest.mark.parametrize("name", ["paper000_circle_high.yaml", "helix_3axis.yaml"])
@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # 1e308 overflows in geometry: a value, not an error
def test_every_key_with_every_bad_value_is_a_suite_error(name: str) -> None:
    """Each key of a shipped scenario, replaced by each bad value: valid, or a CncError (the CLI's one line)."""
    base = yaml.safe_load((SCENARIOS / name).read_text())
    extra = [("servo", "axes"), ("servo", "axes", "x"), ("plant", "axis_overrides"), ("interpolator",)]
    cwd = os.getcwd()
    os.chdir(SCENARIOS)  # relative program files
    try:
        for path in _paths(base) + extra:
            for value in BAD_VALUES:
                raw = copy.deepcopy(base)
                node = raw
                for key in path[:-1]:
                    node = node.setdefault(key, {}) if not isinstance(node.get(key), dict) else node[key]
                    if not isinstance(node, dict):
                        break
                else:
                    node[path[-1]] = value
                    try:
                        build_scenario(raw, base_dir=SCENARIOS)
                    except CncError:
                        pass
    finally:
        os.chdir(cwd)
