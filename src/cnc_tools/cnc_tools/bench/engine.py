"""``cnc-contour bench engine``: this tree's engine against another commit's, side by side in one run.

The other commit is ``--against REV`` (a tag, branch or commit; default the
previous release tag, else ``HEAD~1``: :func:`resolve_against`). Its ``src/``
is extracted with ``git archive`` into a temporary folder and its engine runs
in a child process (its own imports, this environment's packages); this
tree's engine runs in another child. The two
alternate, run after run, on the same scenario, so both see the same machine
load; each run is timed in CPU time of its process (``time.process_time``:
less sensitive to other processes than wall time); the figure that counts is
the ratio of their medians (CPU µs per tick).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.runs.folders import project_root
from cnc_tools.runs.progress import track

#: ``--against``'s default in a repository without a tag before HEAD: the commit before this one.
PREVIOUS_COMMIT = "HEAD~1"
#: ``--against``'s help (the engine and graph benches share the option).
AGAINST_HELP = ("engine and graph benches: the tag, branch or commit whose engine or node graph is the yardstick "
                "(default: the previous release tag, the newest tag before HEAD, if the repository has tags; "
                f"else {PREVIOUS_COMMIT})")
SCENARIO = "scenarios/paper000_circle_high.yaml"
#: The paper's T: both commits run the same loop there (the old per-sample gains are only right at 10 ms).
SAMPLE_TIME_S = 0.01
PACKAGES = ("cnc_contour_control", "cnc_plant_sim", "cnc_tools")

#: Runs in a child: time ``repeats`` engine runs of the scenario, print µs per tick as JSON.
_CHILD = """
import json, sys, time
from cnc_tools.{scenario_module} import load_scenario
from cnc_tools.{engine_module} import run_engine
scenario = load_scenario(sys.argv[1], {{"sample_time_s": float(sys.argv[2])}})
costs = []
for _ in range(int(sys.argv[3])):
    started = time.process_time()
    result = run_engine(scenario)
    elapsed = time.process_time() - started
    ticks = getattr(result, "ticks")
    costs.append(elapsed / ticks * 1e6)
print(json.dumps({{"us_per_tick": costs, "ticks": ticks}}))
"""


def _git(root: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """``git -C root ARGS`` (output captured; a missing git is a CncError naming ``--against``)."""
    try:
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, check=False)
    except FileNotFoundError as err:
        raise CncError(f"--against needs git to read another commit, and git is not installed ({err})") from err


def default_against(root: Path) -> str:
    """``--against``'s default: the newest tag reachable from ``HEAD~1`` if the repository has tags, else ``HEAD~1``."""
    if _git(root, "tag", "--list").stdout.strip():
        described = _git(root, "describe", "--tags", "--abbrev=0", PREVIOUS_COMMIT)
        if described.returncode == 0 and described.stdout.strip():
            return described.stdout.strip()
    return PREVIOUS_COMMIT


def resolve_against(rev: str | None, root: Path) -> tuple[str, str]:
    """``(label, commit hash)`` of ``--against REV`` (None: :func:`default_against`).

    Raises
    ------
    CncError
        ``REV`` names no commit of the repository at ``root`` (the message names ``--against`` and the value).
    """
    name = rev if rev is not None else default_against(root)
    if not name.strip() or name.startswith("-"):
        raise CncError(f"--against must name a tag, branch or commit, got {name!r}")
    found = _git(root, "rev-parse", "--verify", "--quiet", "--end-of-options", f"{name}^{{commit}}")
    commit = found.stdout.strip()
    if found.returncode != 0 or not commit:
        given = "" if rev is not None else " (its default: no tag before HEAD, so the commit before HEAD)"
        raise CncError(f"--against {name!r}{given} names no commit of {root}: give a tag, branch or commit "
                       "hash that git rev-parse knows (a shallow clone lacks older commits)")
    return (name if commit.startswith(name) else f"{name} = {commit[:9]}"), commit


def extract_src(commit: str, root: Path, into: Path) -> Path:
    """``src/`` and ``scenarios/`` of ``commit`` extracted into ``into`` (returns its ``src``).

    Each side runs its own scenario file: gains changed units in the reshape
    (per sample before, per second after), so a file read by the wrong side
    would run another loop. A CncError names the commit if git cannot.
    """
    try:
        archive = subprocess.run(["git", "-C", str(root), "archive", "--format=tar", commit, "src", "scenarios"],
                                 check=True, capture_output=True).stdout
    except (subprocess.CalledProcessError, FileNotFoundError) as err:
        raise CncError(f"--against {commit!r}: cannot read that commit's src/ with git archive ({err})") from err
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into / "src"


def _modules(src: Path) -> tuple[str, str]:
    """Where that tree keeps the scenario and engine modules (before or after the split into trades)."""
    runs = (src / "cnc_tools" / "cnc_tools" / "runs").is_dir()
    return ("runs.scenario", "runs.engine") if runs else ("scenario", "engine")


def time_engine(src: Path, scenario: Path, sample_time_s: float, repeats: int) -> list[float]:
    """µs per tick of ``repeats`` engine runs of the tree at ``src``, in a child process."""
    scenario_module, engine_module = _modules(src)
    code = _CHILD.format(scenario_module=scenario_module, engine_module=engine_module)
    path = ":".join(str(src / p) for p in PACKAGES)
    env = {**os.environ, "PYTHONPATH": f"{path}:{os.environ.get('PYTHONPATH', '')}"}
    done = subprocess.run([sys.executable, "-c", code, str(scenario), str(sample_time_s), str(repeats)],
                          capture_output=True, text=True, env=env, check=False)
    if done.returncode != 0:
        raise CncError(f"engine run of {src} failed: {done.stderr.strip().splitlines()[-1:]}")
    return list(json.loads(done.stdout)["us_per_tick"])


def add_options(parser: argparse.ArgumentParser) -> None:
    """The bench's own options (``cnc-contour bench engine --against REV``)."""
    parser.add_argument("--against", metavar="REV", help=AGAINST_HELP)


def engine_bench(options: argparse.Namespace) -> int:
    """This tree's engine vs ``--against``'s: median µs per tick, alternating rounds, and their ratio."""
    root = project_root()
    against, commit = resolve_against(getattr(options, "against", None), root)
    rounds, repeats = (4, 5) if options.quick else (10, 10)
    sample_time_s = SAMPLE_TIME_S
    load = machine()["load_average_1min"]
    with tempfile.TemporaryDirectory(prefix="cnc_bench_engine_") as tmp:
        theirs_src = extract_src(commit, root, Path(tmp))
        ours_src = root / "src"
        ours: list[float] = []
        theirs: list[float] = []
        for index in track(range(rounds), "engine rounds"):
            print(f"  round {index + 1}/{rounds} ...", flush=True)
            theirs += time_engine(theirs_src, theirs_src.parent / SCENARIO, sample_time_s, repeats)
            ours += time_engine(ours_src, root / SCENARIO, sample_time_s, repeats)
    figures = _figures(against, ours, theirs, load)
    _print(figures)
    write_json(options.json, figures)
    return 0


def _figures(against: str, ours: list[float], theirs: list[float], load: Any) -> dict[str, Any]:
    ours_median, theirs_median = statistics.median(ours), statistics.median(theirs)
    return {"bench": "engine", "scenario": SCENARIO, "sample_time_s": SAMPLE_TIME_S, "against": against,
            "ours_us_per_tick": ours_median, "theirs_us_per_tick": theirs_median,
            "ratio_ours_to_theirs": ours_median / theirs_median, "runs_each": len(ours),
            "load_average_1min_at_start": load, "machine": machine()}


def _print(figures: dict[str, Any]) -> None:
    rows = [["this tree", round(figures["ours_us_per_tick"], 2)],
            [f"commit {figures['against']}", round(figures["theirs_us_per_tick"], 2)]]
    print(format_table(["engine", "CPU µs per tick (median)"], rows))
    print(f"ratio this tree / {figures['against']}: {figures['ratio_ours_to_theirs']:.3f} "
          f"({figures['runs_each']} runs each, alternating; load {figures['load_average_1min_at_start']} at start)")
