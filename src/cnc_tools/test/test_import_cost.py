"""Tier 1: a node process and a ``cnc-contour`` call import what they use, not the suite's analysis stack.

Five node processes start at once on a graph's start, and each imported
scipy.signal (and with it scipy.stats), scipy.optimize and python-control
through the laws' registry: seconds of CPU per graph on two cores. Filter
design, fitting and planning now import them when they run. Checked by
name in a fresh interpreter (timings would depend on the machine).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from cnc_tools.bench.registry import TARGETS

#: Packages no node module and no CLI start-up may import.
HEAVY = ("matplotlib", "toppra", "control", "dask", "distributed", "scipy.signal", "scipy.stats", "scipy.optimize",
         "scipy.interpolate", "scipy.linalg")
MODULES = ("cnc_contour_control.nodes.servo_node", "cnc_contour_control.nodes.interpolator_node",
           "cnc_contour_control.nodes.estimator_node", "cnc_contour_control.nodes.compensator_node",
           "cnc_contour_control.nodes.force_regulator_node", "cnc_plant_sim.nodes.plant_node",
           "cnc_tools.nodes.recorder_node", "cnc_tools.nodes.composed_host", "cnc_tools.cli.main")


@pytest.fixture(scope="module")
def newly_imported() -> dict[str, list[str]]:
    """The heavy packages each module of MODULES adds, imported one after another in one fresh interpreter.

    A module whose import loads a heavy package adds it unless a module before it loaded it already, and that
    one's test fails then: so every module adds none exactly when none of them loads one alone (one
    interpreter, not nine: 0.45 s of CPU each)."""
    code = (f"import importlib, json, sys; heavy = {HEAVY!r}; added = {{}}\n"
            f"for module in {MODULES!r}:\n"
            "    before = {h for h in heavy if h in sys.modules}\n"
            "    importlib.import_module(module)\n"
            "    added[module] = sorted(h for h in heavy if h in sys.modules and h not in before)\n"
            "print(json.dumps(added))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    added: dict[str, list[str]] = json.loads(result.stdout.splitlines()[-1])
    return added


@pytest.mark.parametrize("module", MODULES)
def test_importing_a_node_or_the_cli_loads_no_analysis_package(module: str,
                                                               newly_imported: dict[str, list[str]]) -> None:
    assert newly_imported[module] == [], f"{module} imports them at start-up"


def test_help_lists_every_bench_without_importing_one() -> None:
    code = ("import sys; from cnc_tools.cli.main import main\n"
            "try:\n    main(['bench', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.startswith('cnc_tools.reproductions')))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                            env={**os.environ, "COLUMNS": "2000"})  # argparse wraps help text at hyphens
    assert all(name in result.stdout for name in TARGETS), result.stdout
    assert result.stdout.strip().splitlines()[-1] == "[]", "no paper reproduction imported to list the benches"
