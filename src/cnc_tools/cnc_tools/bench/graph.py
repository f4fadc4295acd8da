"""``cnc-contour bench graph``: the node graph's per-tick cost, this tree against another commit, in one run.

The other commit's ``src/`` and scenario are taken with ``git archive`` and
``git show`` into a temporary folder, beside a temporary prefix whose ``lib/<package>/<executable>``
wrapper scripts start that commit's nodes (its modules first on ``PYTHONPATH``;
the messages come from this tree's install, so they must be the same
``.msg`` files). Each side's own runner (``run_graph`` of that commit) runs in a
child process, with the wrapper prefix first on ``AMENT_PREFIX_PATH`` for the
other commit, so its ``find_executable`` starts the wrappers.

A child runs the scenario at T = 10 ms and 1 ms, plus a 2-tick run whose CPU
(starting, connecting and stopping the processes) is taken out, as the
``lockstep`` bench does. Per tick: the CPU (user + system, ``RUSAGE_CHILDREN``
of the runner: every node process) and the wall time (the plant's summary).
The sides alternate, round by round and in swapped order, so both see the
same machine load; the figures that count are the ratios of their medians.
Every graph run gets a random ROS domain and the runner's loopback DDS
policy; a stop signal to the bench stops the child runner, which stops its
nodes.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.core.stages import pipeline
from cnc_tools.analysis.tables import format_table, machine, write_json
from cnc_tools.bench.engine import PACKAGES, extract_src, resolve_against
from cnc_tools.runs.dds import MAX_RANDOM_DOMAIN_ID
from cnc_tools.runs.folders import project_root, timestamp
from cnc_tools.runs.graph import POLL_S
from cnc_tools.runs.lifetime import check_stop, die_with_parent, runner_stop_signals, stop_process
from cnc_tools.runs.progress import track

SCENARIO = "scenarios/paper000_circle_high.yaml"
SAMPLE_TIMES_S = (0.01, 0.001)
#: The executables a (recorded) graph run starts, by package.
EXECUTABLES = {"cnc_plant_sim": ("plant",), "cnc_contour_control": ("interpolator", "servo"),
               "cnc_tools": ("recorder",)}
#: ``name = module:function`` in a setup.py's console_scripts.
_ENTRY_POINT = re.compile(r"""["']\s*([\w-]+)\s*=\s*([\w.]+)\s*:\s*(\w+)\s*["']""")


@dataclass(frozen=True)
class Plan:
    """How long a bench run measures: alternating rounds, simulated seconds per sample time."""

    rounds: int
    duration_s: dict[float, float]


FULL = Plan(5, {0.01: 10.0, 0.001: 5.0})
QUICK = Plan(2, {0.01: 3.0, 0.001: 1.5})

#: Runs in a child, on the imports of one tree: a 2-tick run, then one run per sample time; prints JSON.
_CHILD = """
import json, os, random, resource, signal, sys
from pathlib import Path
signal.signal(signal.SIGTERM, signal.default_int_handler)  # an old runner stops its nodes on SIGTERM too
from cnc_tools.{scenario_module} import load_scenario
from cnc_tools.{graph_module} import run_graph

def cpu_s():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime

def run(sample_time_s, duration_s, run_dir):
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, {max_domain}))
    scenario = load_scenario(sys.argv[1], {{"sample_time_s": sample_time_s, "duration_s": duration_s}})
    before = cpu_s()
    summary = run_graph(scenario, run_dir, record=sys.argv[3] == "1").summary
    return {{"cpu_s": cpu_s() - before, "ticks": summary["ticks"], "wall_s": summary["wall_time_s"],
            "status": summary.get("status"), "faults": summary.get("faults", [])}}

out = Path(sys.argv[2])
runs = {{"startup": run(0.01, 0.01, out / "startup")}}
for sample_time_s, duration_s in json.loads(sys.argv[4]):
    runs[repr(sample_time_s)] = run(sample_time_s, duration_s, out / f"T{{sample_time_s * 1e3:g}}ms")
print(json.dumps(runs))
"""


@dataclass(frozen=True)
class Side:
    """One tree under test: its sources, its scenario file and the environment its runner gets."""

    label: str
    src: Path
    scenario: Path
    env: dict[str, str]


def graph_modules(src: Path) -> tuple[str, str]:
    """Where the tree at ``src`` keeps the scenario loader and ``run_graph`` (before or after the split into trades)."""
    tools = src / "cnc_tools" / "cnc_tools"
    for scenario_module, graph_module in (("runs.scenario", "runs.graph"), ("scenario", "runner")):
        if (tools / f"{graph_module.replace('.', '/')}.py").is_file():
            return scenario_module, graph_module
    raise CncError(f"no node-graph runner in {tools} (looked for runs/graph.py and runner.py)")


def entry_points(setup_py: Path) -> dict[str, tuple[str, str]]:
    """``{executable: (module, function)}`` of a package's console_scripts, read from its setup.py."""
    return {name: (module, function) for name, module, function in _ENTRY_POINT.findall(setup_py.read_text())}


def write_wrappers(src: Path, prefix: Path, python: str = sys.executable) -> list[Path]:
    """``prefix/lib/<package>/<executable>`` scripts starting the nodes of the tree at ``src``.

    Each puts the tree's package folders first on ``PYTHONPATH`` and execs
    ``python -c "... main()"`` with the node's arguments, as ``ros2 run`` would.
    """
    path = ":".join(str(src / package) for package in PACKAGES)
    written = []
    for package, executables in EXECUTABLES.items():
        points = entry_points(src / package / "setup.py")
        for executable in executables:
            if executable not in points:
                raise CncError(f"{src / package / 'setup.py'} declares no console script {executable!r}")
            module, function = points[executable]
            script = prefix / "lib" / package / executable
            script.parent.mkdir(parents=True, exist_ok=True)
            script.write_text(f'#!/bin/sh\nPYTHONPATH="{path}${{PYTHONPATH:+:$PYTHONPATH}}" exec "{python}" '
                              f'-c "import sys; from {module} import {function}; sys.exit({function}())" "$@"\n')
            script.chmod(0o755)
            written.append(script)
    return written


def other_side(commit: str, root: Path, tmp: Path) -> Side:
    """The tree of ``commit``: its src/ and scenario extracted into ``tmp``, its nodes behind wrappers."""
    src = extract_src(commit, root, tmp / "tree")
    scenario = tmp / "tree" / SCENARIO
    scenario.parent.mkdir(parents=True, exist_ok=True)
    scenario.write_bytes(_git_show(root, commit, SCENARIO))
    write_wrappers(src, tmp / "prefix")
    path = ":".join(str(src / package) for package in PACKAGES)
    env = {**os.environ, "PYTHONPATH": f"{path}:{os.environ.get('PYTHONPATH', '')}",
           "AMENT_PREFIX_PATH": f"{tmp / 'prefix'}:{os.environ.get('AMENT_PREFIX_PATH', '')}"}
    return Side(f"commit {commit}", src, scenario, env)


def _git_show(root: Path, commit: str, path: str) -> bytes:
    try:
        return subprocess.run(["git", "-C", str(root), "show", f"{commit}:{path}"],
                              check=True, capture_output=True).stdout
    except (subprocess.CalledProcessError, FileNotFoundError) as err:
        raise CncError(f"--against {commit!r}: cannot read {path} of that commit ({err})") from err


#: Where the suite's message definitions live (repository path).
MSG_FOLDER = "src/cnc_contour_interfaces/msg"


def graph_messages(root: Path) -> list[str]:
    """The ``.msg`` files the core graph's nodes exchange, nested types included (repository paths)."""
    folder = root / MSG_FOLDER
    package = "cnc_contour_interfaces/msg/"
    names = {t[len(package):] for t in pipeline(("x", "y")).recorded_topics().values() if t.startswith(package)}
    pending = sorted(names)
    while pending:
        for line in (folder / f"{pending.pop()}.msg").read_text().splitlines():
            words = line.split("#", 1)[0].split()
            field_type = words[0].split("[", 1)[0] if words else ""
            if field_type not in names and (folder / f"{field_type}.msg").is_file():
                names.add(field_type)
                pending.append(field_type)
    return [f"{MSG_FOLDER}/{name}.msg" for name in sorted(names)]


def require_same_messages(root: Path, commit: str) -> None:
    """The other commit's nodes use this tree's messages: refuse if a ``.msg`` file the core graph exchanges differs.

    Messages only the optional stages exchange (``ContourError``,
    ``Compensation``, ...) may differ: the core graph never sends them. Fields
    this tree added (lines only added, none removed or changed, e.g. ``Path``'s
    ``path_tolerance_m``) are allowed: the other commit's nodes leave them at
    their defaults.
    """
    diff = subprocess.run(["git", "-C", str(root), "diff", "-U0", commit, "--", *graph_messages(root)],
                          capture_output=True, text=True, check=False)
    if diff.returncode != 0:
        raise CncError(f"--against {commit!r}: git cannot compare its messages ({diff.stderr.strip()})")
    changed = [line for line in diff.stdout.splitlines()
               if line.startswith("-") and not line.startswith("---") and line[1:].split("#", 1)[0].strip()]
    if changed:
        raise CncError(f"--against {commit!r}: its messages differ from this tree's (lines {changed!r} "
                       "removed or changed); build that commit with colcon to compare graphs")


def run_side(side: Side, run_dir: Path, record: bool, plan: Plan) -> dict[str, Any]:
    """One child of ``side``: its runs' CPU, ticks and wall time (a CncError if one did not finish cleanly)."""
    scenario_module, graph_module = graph_modules(side.src)
    code = _CHILD.format(scenario_module=scenario_module, graph_module=graph_module, max_domain=MAX_RANDOM_DOMAIN_ID)
    durations = json.dumps([[t, plan.duration_s[t]] for t in SAMPLE_TIMES_S])
    command = [sys.executable, "-c", code, str(side.scenario), str(run_dir), "1" if record else "0", durations]
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / "runner.out", "wb") as out, open(run_dir / "runner.log", "wb") as err:
        child = subprocess.Popen(command, stdout=out, stderr=err, env=side.env, start_new_session=True,
                                 preexec_fn=die_with_parent())
        returncode = _wait_child(child)
    output, errors = (run_dir / "runner.out").read_text(), (run_dir / "runner.log").read_text(errors="replace")
    if returncode != 0:
        raise CncError(f"graph run of {side.label} failed (exit {returncode}): {errors.strip().splitlines()[-3:]}")
    runs = json.loads(output.strip().splitlines()[-1])
    for name, figures in runs.items():
        if figures["status"] != "finished" or figures["faults"]:
            raise CncError(f"graph run {name} of {side.label} ended {figures['status']}: {figures['faults']}")
    return runs


def _wait_child(child: subprocess.Popen[bytes]) -> int:
    """The child's exit code; on SIGINT, SIGTERM or SIGHUP to the bench the child is stopped first."""
    with runner_stop_signals() as signals:
        try:
            while child.poll() is None:
                check_stop(signals)
                time.sleep(POLL_S)
        except BaseException:
            stop_process(child, 30.0)
            raise
    return child.returncode


def per_tick(runs: dict[str, Any]) -> dict[float, tuple[float, float]]:
    """``{T: (CPU s per tick without start-up, wall s per tick)}`` of one child's runs."""
    startup_s = float(runs["startup"]["cpu_s"])
    return {t: (max(float(runs[repr(t)]["cpu_s"]) - startup_s, 0.0) / int(runs[repr(t)]["ticks"]),
                float(runs[repr(t)]["wall_s"]) / int(runs[repr(t)]["ticks"])) for t in SAMPLE_TIMES_S}


def add_options(parser: argparse.ArgumentParser) -> None:
    """The bench's own option (``--against`` is the engine bench's, shared)."""
    parser.add_argument("--record", action="store_true",
                        help="graph bench: record both sides' runs to bags (the recorder's cost included)")


def graph_bench(options: argparse.Namespace) -> int:
    """This tree's node graph vs ``--against``'s: median CPU and wall per tick, alternating, and their ratios."""
    root = project_root()
    against, commit = resolve_against(getattr(options, "against", None), root)
    plan, record = (QUICK if options.quick else FULL), bool(getattr(options, "record", False))
    run_dir = options.out or root / "bags" / "bench" / "graph" / timestamp()
    load = machine()["load_average_1min"]
    require_same_messages(root, commit)
    print(f"graph bench ({'quick' if options.quick else 'full'}, {'recorded' if record else 'not recorded'}) "
          f"on {SCENARIO}, this tree against {against}; run files in {run_dir}", flush=True)
    samples: dict[str, list[dict[float, tuple[float, float]]]] = {"ours": [], "theirs": []}
    with tempfile.TemporaryDirectory(prefix="cnc_bench_graph_") as tmp:
        sides = {"theirs": other_side(commit, root, Path(tmp)),
                 "ours": Side("this tree", root / "src", root / SCENARIO, dict(os.environ))}
        for index in track(range(plan.rounds), "graph rounds"):
            order = ("theirs", "ours") if index % 2 == 0 else ("ours", "theirs")
            for key in order:
                runs = run_side(sides[key], run_dir / f"round{index + 1}" / key, record, plan)
                samples[key].append(per_tick(runs))
                print(f"  round {index + 1}/{plan.rounds}, {sides[key].label}: " + _progress(samples[key][-1]),
                      flush=True)
    figures = collect(against, record, plan, samples, load)
    print_figures(figures)
    write_json(options.json, figures)
    return 0


def _progress(sample: dict[float, tuple[float, float]]) -> str:
    return "; ".join(f"T = {t * 1e3:g} ms: CPU/tick {cpu_s * 1e6:.0f} us, wall/tick {wall_s * 1e6:.0f} us"
                     for t, (cpu_s, wall_s) in sample.items())


def collect(against: str, record: bool, plan: Plan, samples: dict[str, list[dict[float, tuple[float, float]]]],
            load: Any) -> dict[str, Any]:
    """Medians per side and sample time, their ratios (this tree / the other), as plain types."""
    rows = []
    for t in SAMPLE_TIMES_S:
        median = {key: [statistics.median(s[t][i] for s in samples[key]) for i in (0, 1)] for key in samples}
        rows.append({"sample_time_s": t, "duration_s": plan.duration_s[t],
                     "ours_cpu_per_tick_s": median["ours"][0], "theirs_cpu_per_tick_s": median["theirs"][0],
                     "ours_wall_per_tick_s": median["ours"][1], "theirs_wall_per_tick_s": median["theirs"][1],
                     "cpu_ratio": median["ours"][0] / median["theirs"][0],
                     "wall_ratio": median["ours"][1] / median["theirs"][1]})
    return {"bench": "graph", "scenario": SCENARIO, "against": against, "recorded": record,
            "rounds": plan.rounds, "rows": rows,
            "per_round_cpu_wall_per_tick_s": {key: [{repr(t): list(v) for t, v in s.items()} for s in runs]
                                              for key, runs in samples.items()},
            "load_average_1min_at_start": load, "machine": machine()}


def print_figures(figures: dict[str, Any]) -> None:
    """One row per sample time: both sides' medians and the ratios."""
    against = figures["against"]
    print(format_table(["T [ms]", "CPU/tick ours [us]", f"CPU/tick {against} [us]", "CPU ratio",
                        "wall/tick ours [us]", f"wall/tick {against} [us]", "wall ratio"], [
        [r["sample_time_s"] * 1e3, r["ours_cpu_per_tick_s"] * 1e6, r["theirs_cpu_per_tick_s"] * 1e6, r["cpu_ratio"],
         r["ours_wall_per_tick_s"] * 1e6, r["theirs_wall_per_tick_s"] * 1e6, r["wall_ratio"]]
        for r in figures["rows"]]))
    start, end = figures["load_average_1min_at_start"], figures["machine"]["load_average_1min"]
    print(f"ratios this tree / {against} (medians of {figures['rounds']} runs each, alternating; "
          f"{'recorded' if figures['recorded'] else 'not recorded'}; load {start:.2f} at start, {end:.2f} at end)")
