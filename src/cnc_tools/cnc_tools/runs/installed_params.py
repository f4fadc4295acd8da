"""The parameter files the packages install (``share/<package>/config/``), made from scenarios by the runner's code.

Each entry of :data:`INSTALLED` is a scenario whose graph is installed as one
ROS 2 parameters file (:mod:`cnc_contour_control.graph.graph_params`) beside its
program::

    src/cnc_contour_control/config/paper000_circle_high.params.yaml           /**, /cnc/plant, /cnc/servo_x, ...
    src/cnc_contour_control/config/paper000_circle_high.recorded.params.yaml  the same with /cnc/recorder
    src/cnc_contour_control/config/paper000_circle_high.program.yaml          the program the interpolator reads

The nodes' parameters are those the runner starts them with
(:func:`cnc_tools.runs.graph_nodes.graph_specs`; in the recorded graph as in a
recorded run, the recorder's without its ``output``, given at start), with two
differences a file outside a run folder needs: the program file is named
relative to the parameters file's folder (the launch file starts the nodes
there), and the plant writes no summary file (it reports the run's end on
``/diagnostics``; ``-p summary_file:=...`` asks for one). The files are
committed, the packages' ``setup.py`` installs them, and
``cnc-contour config-files --check`` (and a test) says whether they are still
what the code makes of their scenarios.
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.graph.graph_params import graph_params_yaml
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.graph_nodes import NAMESPACE, NodeSpec, graph_specs, recorder_spec, write_program
from cnc_tools.runs.scenario import load_scenario


@dataclass(frozen=True)
class InstalledGraph:
    """A scenario whose graph a package installs: ``<package>/config/<scenario>.params.yaml`` and its program."""

    package: str
    scenario: str

    @property
    def params_file(self) -> str:
        """The parameters file's name."""
        return f"{self.scenario}.params.yaml"

    @property
    def recorded_params_file(self) -> str:
        """The parameters file of the graph recorded by the suite's recorder (a node of it)."""
        return f"{self.scenario}.recorded.params.yaml"

    @property
    def program_file(self) -> str:
        """The program file's name (as the parameters file names it: relative to its folder)."""
        return f"{self.scenario}.program.yaml"


#: The installed graphs; the first is the launch file's default.
INSTALLED: tuple[InstalledGraph, ...] = (InstalledGraph("cnc_contour_control", "paper000_circle_high"),)


def config_dir(entry: InstalledGraph, root: Path | None = None) -> Path:
    """The package's source folder of installed config files."""
    return (root or project_root()) / "src" / entry.package / "config"


def installed_files(entry: InstalledGraph, root: Path | None = None) -> dict[str, str]:
    """File name -> text of the graph ``entry``, generated now from ``scenarios/<scenario>.yaml``.

    Two parameters files: the graph alone, and the graph recorded by the
    suite's recorder, which every stage then waits for as the runner's stages
    do (``extra_subscribers=1``, a required reader ``recorder``), so the bag
    holds the run from its first tick whatever the order the nodes start in.
    """
    scenario = load_scenario((root or project_root()) / "scenarios" / f"{entry.scenario}.yaml")
    if "gcode_file" in scenario.raw["program"]:
        raise ConfigError(f"installed graph {entry.scenario}: a G-code program would be named by an absolute path")
    with tempfile.TemporaryDirectory() as folder:
        program = write_program(scenario, Path(folder)).read_text()
        recorder = recorder_spec(scenario, Path(folder) / "bag")
        graphs = {entry.params_file: graph_specs(scenario, Path(folder)),
                  entry.recorded_params_file: [
                      NodeSpec(recorder.package, recorder.executable, recorder.name,
                               {k: v for k, v in recorder.parameters.items() if k != "output"}),
                      *graph_specs(scenario, Path(folder), 1, extra_readers=[recorder.name])]}
        relocated = {"program_file": entry.program_file, "summary_file": ""}
        texts = {name: graph_params_yaml(NAMESPACE, [(spec.name, _relocate(spec, relocated)) for spec in specs])
                 for name, specs in graphs.items()}
        if any(folder in text for text in texts.values()):
            raise ConfigError(f"installed graph {entry.scenario}: a parameter names the generating folder: {texts}")
    return {**texts, entry.program_file: program}


def _relocate(spec: NodeSpec, values: dict[str, str]) -> dict[str, object]:
    """``spec``'s parameters with the run-folder paths in ``values`` replaced where the node has them."""
    return {key: values.get(key, value) for key, value in spec.parameters.items()}


def stale_files(root: Path | None = None) -> list[Path]:
    """The installed files whose committed text is not what the code generates now (missing ones too)."""
    stale = []
    for entry in INSTALLED:
        for name, text in installed_files(entry, root).items():
            path = config_dir(entry, root) / name
            if not path.is_file() or path.read_text() != text:
                stale.append(path)
    return stale


def write_installed(root: Path | None = None) -> list[Path]:
    """Write every installed file from its scenario; the paths written."""
    written = []
    for entry in INSTALLED:
        folder = config_dir(entry, root)
        folder.mkdir(parents=True, exist_ok=True)
        for name, text in installed_files(entry, root).items():
            (folder / name).write_text(text)
            written.append(folder / name)
    return written
