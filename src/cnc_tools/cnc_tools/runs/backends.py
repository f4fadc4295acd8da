"""One call for a run on either back end: ``run_scenario(scenario, backend="graph" | "engine")``.

Both give a :class:`~cnc_tools.run_record.RunRecord`: the node graph through
its recorded bag (read back, with the plant's summary), the engine directly.
With ``run_dir`` an engine run writes the same run folder a graph run leaves
(``bag/``, ``summary.json``, ``scenario.yaml``; the scores and plots come from
:func:`cnc_tools.runs.outputs.write_run_outputs`), so the two are handled alike.
"""
from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from cnc_contour_control.core.config import require_choice
from cnc_contour_control.core.errors import FaultError
from cnc_tools.run_record import RunRecord
from cnc_tools.runs.engine import EngineFault, run_engine
from cnc_tools.runs.scenario import Scenario

#: A back end: (scenario, run folder or None, options) -> run record.
Backend = Callable[..., RunRecord]


def run_on_graph(scenario: Scenario, run_dir: Path | None = None, **options: Any) -> RunRecord:
    """Run through the node graph, recorded to ``run_dir/bag`` (a temporary folder if None), and read it back."""
    from cnc_tools.bagio.bag import read_bag  # rosbags: loaded only for graph runs
    from cnc_tools.runs.graph import run_graph

    if run_dir is None:
        import tempfile

        run_dir = Path(tempfile.mkdtemp(prefix=f"cnc_{scenario.name}_"))
    result = run_graph(scenario, run_dir, record=True, **options)
    if result.faults or result.bag_path is None:
        raise FaultError(f"{scenario.name}: node-graph run in {run_dir} faulted: {result.faults}")
    return read_bag(result.bag_path).with_(summary=result.summary, backend="graph", name=scenario.name)


def run_on_engine(scenario: Scenario, run_dir: Path | None = None, **options: Any) -> RunRecord:
    """Run in-process; with ``run_dir``, write the run folder a graph run leaves: bag, summary, scenario.

    A run that faults raises :class:`EngineFault` after its folder (every tick before the fault) is written.
    """
    try:
        record = run_engine(scenario, run_dir=run_dir, **options)
    except EngineFault as fault:
        _write_folder(run_dir, scenario, fault.record)
        raise
    _write_folder(run_dir, scenario, record)
    return record


def _write_folder(run_dir: Path | None, scenario: Scenario, record: RunRecord) -> None:
    if run_dir is not None:
        from cnc_tools.bagio.record_bag import write_record_bag  # rosbags: loaded only when writing

        write_run_folder(run_dir, scenario, record.summary)
        write_record_bag(record, run_dir / "bag")


#: Back ends by name.
BACKENDS: dict[str, Backend] = {"graph": run_on_graph, "engine": run_on_engine}


def run_scenario(scenario: Scenario, backend: str = "graph", run_dir: Path | None = None,
                 **options: Any) -> RunRecord:
    """Run ``scenario`` on ``backend`` (``"graph"`` or ``"engine"``) and return its run record."""
    require_choice("backend", backend, BACKENDS)
    return BACKENDS[backend](scenario, run_dir, **options)


def write_run_folder(run_dir: Path, scenario: Scenario, summary: dict[str, Any] | Any) -> None:
    """The files every run folder holds besides the bag: ``summary.json`` and the scenario as run."""
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "summary.json").write_text(json.dumps(dict(summary), indent=2, default=str))
    (run_dir / "scenario.yaml").write_text(yaml.safe_dump(dict(scenario.raw), sort_keys=False))
