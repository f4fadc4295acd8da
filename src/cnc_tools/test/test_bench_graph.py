"""The graph bench's pure parts (module paths, entry points, wrappers, message check, arithmetic); NumPy in JSON.

No graph runs and no timing assertions: a wrapper is checked by running it on
a small fake tree (it must import the tree's module, pass the arguments on and
return its exit code).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import write_json
from cnc_tools.bench.engine import PACKAGES
from cnc_tools.bench.graph import (
    EXECUTABLES,
    SAMPLE_TIMES_S,
    entry_points,
    graph_bench,
    graph_messages,
    graph_modules,
    per_tick,
    require_same_messages,
    write_wrappers,
)
from cnc_tools.bench.registry import get_bench
from cnc_tools.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[3]

#: A node module of the fake tree: prints where it was imported from and its arguments, exits with 3.
FAKE_NODE = """import json, sys
def main():
    print(json.dumps({"file": __file__, "argv": sys.argv[1:]}))
    return 3
"""


def fake_tree(src: Path, skip: str = "") -> Path:
    """A tree whose packages declare every wrapped executable as ``fake_<executable>:main``."""
    for package in PACKAGES:
        folder = src / package
        folder.mkdir(parents=True)
        lines = [f'            "{exe} = fake_{exe}:main",' for exe in EXECUTABLES.get(package, ()) if exe != skip]
        (folder / "setup.py").write_text('setup(entry_points={\n    "console_scripts": [\n'
                                         + "\n".join(lines) + "\n    ],\n})\n")
        for exe in EXECUTABLES.get(package, ()):
            (folder / f"fake_{exe}.py").write_text(FAKE_NODE)
    return src


def test_modules_of_this_tree_are_the_trades() -> None:
    assert graph_modules(ROOT / "src") == ("runs.scenario", "runs.graph")


def test_modules_before_the_split_are_flat(tmp_path: Path) -> None:
    tools = tmp_path / "cnc_tools" / "cnc_tools"
    tools.mkdir(parents=True)
    (tools / "runner.py").write_text("")
    assert graph_modules(tmp_path) == ("scenario", "runner")


def test_a_tree_without_runner_is_refused(tmp_path: Path) -> None:
    with pytest.raises(CncError, match="no node-graph runner"):
        graph_modules(tmp_path)


@pytest.mark.parametrize(("package", "executable", "module"), [
    ("cnc_plant_sim", "plant", "cnc_plant_sim.nodes.plant_node"),
    ("cnc_contour_control", "servo", "cnc_contour_control.nodes.servo_node"),
    ("cnc_tools", "recorder", "cnc_tools.nodes.recorder_node"),
])
def test_entry_points_read_from_setup_py(package: str, executable: str, module: str) -> None:
    assert entry_points(ROOT / "src" / package / "setup.py")[executable] == (module, "main")


def test_wrappers_run_the_tree_module_with_the_arguments(tmp_path: Path) -> None:
    src = fake_tree(tmp_path / "src")
    scripts = write_wrappers(src, tmp_path / "prefix")
    assert sorted(p.relative_to(tmp_path / "prefix").as_posix() for p in scripts) == sorted(
        f"lib/{package}/{exe}" for package, exes in EXECUTABLES.items() for exe in exes)
    done = subprocess.run([str(tmp_path / "prefix" / "lib" / "cnc_plant_sim" / "plant"), "--ros-args", "-r", "a:=y"],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 3, done.stderr
    printed = json.loads(done.stdout)
    assert printed == {"file": str(src / "cnc_plant_sim" / "fake_plant.py"), "argv": ["--ros-args", "-r", "a:=y"]}


def test_a_missing_console_script_is_named(tmp_path: Path) -> None:
    src = fake_tree(tmp_path / "src", skip="servo")
    with pytest.raises(CncError, match="declares no console script 'servo'"):
        write_wrappers(src, tmp_path / "prefix", python=sys.executable)


def test_messages_of_the_baseline_are_this_tree_s() -> None:
    require_same_messages(ROOT, "fd8ef2a")


def test_the_core_graph_messages_include_the_nested_ones_and_not_the_optional_stages() -> None:
    names = {Path(m).stem for m in graph_messages(ROOT)}
    assert {"Reference", "Path", "PathSegment", "AxisCommand"} <= names
    assert not names & {"ContourError", "Compensation"}


def test_an_unknown_commit_is_refused() -> None:
    with pytest.raises(CncError, match="--against .no-such-rev.: git cannot compare"):
        require_same_messages(ROOT, "no-such-rev")


def test_per_tick_takes_the_start_up_out() -> None:
    runs = {"startup": {"cpu_s": 2.0}, repr(0.01): {"cpu_s": 3.0, "ticks": 500, "wall_s": 0.5},
            repr(0.001): {"cpu_s": 4.0, "ticks": 1000, "wall_s": 1.5}}
    figures = per_tick(runs)
    assert set(figures) == set(SAMPLE_TIMES_S)
    assert figures[0.01] == pytest.approx((2e-3, 1e-3))
    assert figures[0.001] == pytest.approx((2e-3, 1.5e-3))


def test_graph_bench_is_registered_with_its_options() -> None:
    assert get_bench("graph") is graph_bench
    options = build_parser().parse_args(["bench", "graph", "--against", "HEAD~1", "--record", "--quick"])
    assert (options.against, options.record, options.quick) == ("HEAD~1", True, True)


def test_figures_with_numpy_scalars_are_written_as_json(tmp_path: Path) -> None:
    path = tmp_path / "figures.json"
    write_json(path, {"met": np.float64(150.0) >= 100.0, "ratio": np.float64(1.5)})
    assert json.loads(path.read_text()) == {"met": True, "ratio": 1.5}
