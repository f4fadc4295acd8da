"""A run's verdict, from the run itself: complete, partial or faulted (ROS-free, no rosbags).

A bag whose index matches its ``metadata.yaml`` says only that the file is
intact, not that the run behind it ended well. The verdict asks the run:

* **its end**: the plant's ``summary.json`` (status ``finished`` with ``ticks``)
  or its :data:`~cnc_contour_control.core.topics.RUN_FINISHED` status on
  ``/diagnostics`` with :data:`~cnc_contour_control.core.topics.TICKS_KEY`; neither
  means the run did not finish (killed, interrupted) or its end is unknown;
* **every per-tick topic** of the run's pipeline
  (:meth:`~cnc_contour_control.core.stages.Pipeline.per_tick_topics`) holds one
  message per finished tick, with contiguous stamps (lockstep: spaced by T)
  shared with ``joint_states``;
* **faults**: in ``summary.json`` and as ERROR statuses on ``/diagnostics``; an
  e-stop latched during the run (``estop_latches``) and a guard that stopped
  the compensator (``compensator.fault``) are faults too: the machine did not
  do what the run asked, whatever the contour looks like;
* **the program's end**: a run that ends by its program (no ``duration_s`` of
  its own, ``ends_by: program`` in the summary) needs its reference to have
  reached the program's end; once the reference has, every axis must stand
  within ``end_tolerance_m`` of the program's end point at the last sample.
  An e-stop that left the axes short, or a run cut before its program ended,
  is partial; a run told to end at its ``duration_s`` (``ends_by: duration``)
  may end with its program unfinished;
* **non-finite samples** (NaN, inf) in positions, references and commands,
  each reported with its topic and the time of the first one;
* **the file**: a bag salvaged record by record is partial.

``faulted`` wins over ``partial``; ``complete`` needs all of the above to hold.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cnc_contour_control.core import topics as t
from cnc_contour_control.core.stages import pipeline
from cnc_tools.run_record import IntArray, RunRecord

#: Verdicts, best first.
VERDICTS = ("complete", "partial", "faulted")
#: How far from the program's end point the axes may stand when a run that ends by its program ends [m]
#: (the summary's ``end_tolerance_m`` overrides it): catches an axis left short (e-stop, a stop, a cut run),
#: not a loop's settling error.
END_TOLERANCE_M = 5.0e-4
#: ``DiagnosticStatus.ERROR``: a fault of the node that sent it (STALE, 3, is a node waiting for a partner: no fault).
ERROR_LEVEL = 2
#: Record attribute of each optional stage's per-tick series, by stage name.
_STAGE_SERIES = {"estimator": "contour_error", "compensator": "compensation", "force_regulator": "feed_override"}


@dataclass(frozen=True)
class Status:
    """One status of ``/diagnostics``: level (0 OK, 1 WARN, 2 ERROR, 3 STALE), node, message, key values."""

    level: int
    name: str
    message: str
    values: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class NonFinite:
    """Non-finite samples of one topic's field: how many rows, and the stamp of the first (ns)."""

    topic: str
    field: str
    count: int
    first_stamp_ns: int

    def describe(self) -> str:
        """One phrase for people."""
        return (f"non-finite {self.field} on {self.topic} at t = {self.first_stamp_ns * 1e-9:.6f} s"
                f"{f' ({self.count} samples)' if self.count > 1 else ''}")


@dataclass(frozen=True)
class Verdict:
    """How a run ended and whether its record is whole.

    Attributes
    ----------
    status : str
        One of :data:`VERDICTS`.
    reasons : tuple of str
        Why it is not complete (empty when it is).
    ticks : int or None
        The ticks the run finished with, None when it did not finish (or its end is unknown).
    non_finite : tuple of NonFinite
        Non-finite samples found.
    """

    status: str
    reasons: tuple[str, ...] = ()
    ticks: int | None = None
    non_finite: tuple[NonFinite, ...] = ()

    @property
    def complete(self) -> bool:
        """True for a run that finished without fault, recorded whole."""
        return self.status == "complete"

    def describe(self) -> str:
        """One line: the status in capitals, then the reasons."""
        if self.complete:
            return f"COMPLETE ({self.ticks} ticks, every per-tick topic whole and contiguous, no fault)"
        return f"{self.status.upper()}: " + "; ".join(self.reasons)

    def to_dict(self) -> dict[str, Any]:
        """Plain data for JSON."""
        return {"status": self.status, "reasons": list(self.reasons), "ticks": self.ticks,
                "non_finite": [{"topic": n.topic, "field": n.field, "count": n.count,
                                "first_time_s": n.first_stamp_ns * 1e-9} for n in self.non_finite],
                "description": self.describe()}


def judge(record: RunRecord, statuses: Sequence[Status] = (), namespace: str = t.DEFAULT_NAMESPACE) -> Verdict:
    """The verdict of the run behind ``record`` (its ``summary``), given its ``/diagnostics`` ``statuses``.

    ``namespace`` only names the topics in the reasons.
    """
    summary = dict(getattr(record, "summary", None) or {})
    statuses = _own_statuses(statuses, summary)
    faults = _faults(summary, statuses)
    non_finite = find_non_finite(record, namespace)
    ticks, end_problems = _finished_ticks(summary, statuses)
    gaps = [] if ticks is None else _gaps(record, ticks, _period_ns(summary, record), namespace)
    file_problems = [] if record.integrity.complete else [f"bag {record.integrity.describe()}"]
    program = [] if ticks is None or faults else program_end_problems(record, summary)
    partial = [*end_problems, *gaps, *file_problems, *program]
    status = "faulted" if faults or non_finite else "partial" if partial else "complete"
    reasons = (*faults, *(n.describe() for n in non_finite), *partial)
    return Verdict(status, tuple(reasons), ticks, tuple(non_finite))


def _own_statuses(statuses: Sequence[Status], summary: Mapping[str, Any]) -> list[Status]:
    """The statuses of this run: those of another run id are dropped when the run's id is known."""
    run_id = summary.get(t.RUN_ID_KEY)
    return [s for s in statuses if run_id is None or s.values.get(t.RUN_ID_KEY, run_id) == run_id]


def _faults(summary: Mapping[str, Any], statuses: Iterable[Status]) -> list[str]:
    """Faults of the run, each once: the summary's, then ERROR statuses of its nodes."""
    found = [str(f) for f in summary.get("faults") or []]
    if summary.get("status") == "faulted" and not found:
        found.append(f"summary.json says faulted: {summary.get('reason') or 'no reason given'}")
    latches = int(summary.get("estop_latches") or 0)
    if latches:
        found.append(f"the e-stop latched {latches} time{'s' if latches > 1 else ''} during the run "
                     "(summary.json estop_latches): the machine stopped")
    compensator = summary.get("compensator")
    if isinstance(compensator, Mapping) and compensator.get("fault"):
        found.append(f"the compensator's guard stopped it: {compensator['fault']}")
    for status in statuses:
        if status.level == ERROR_LEVEL and not any(status.message in f for f in found):
            found.append(f"{status.name}: {status.message}" if status.name else status.message)
    return found


def program_end_problems(record: RunRecord, summary: Mapping[str, Any]) -> list[str]:
    """Why a run did not end its program: the reference short of the program's end (unless the run ends by its own
    duration), or, once the reference ended it, an axis away from the program's end point by more than the end
    tolerance at the last sample. None when it ended it."""
    reference, positions = record.reference, record.joint_states.position_m
    if reference is None or not len(reference.done) or not len(positions):
        return []
    if not bool(reference.done[-1]):
        if summary.get("ends_by", "program") == "duration":
            return []  # cut by its own duration_s, as asked
        done_s, total_s = float(reference.path_length_m[-1]), float(record.program.total_length_m)
        return [f"the program did not finish: the reference stood at {1e3 * done_s:.3f} of {1e3 * total_s:.3f} mm "
                f"of the path when the run ended"]
    tolerance_m = float(summary.get("end_tolerance_m") or END_TOLERANCE_M)
    end = np.asarray(record.program.end_m, float)
    last = np.asarray(positions[-1], float)[:end.size]
    off = np.abs(last - end)
    if not np.all(off <= tolerance_m):
        worst = int(np.argmax(off))
        axes = ", ".join(f"{name} {1e3 * d:.3f}" for name, d in zip(record.axis_names, off))
        return [f"the program did not finish: axis {record.axis_names[worst]} ended {1e3 * off[worst]:.3f} mm from "
                f"the program's end point ({axes} mm; end tolerance {1e3 * tolerance_m:g} mm)"]
    return []


def _finished_ticks(summary: Mapping[str, Any], statuses: Iterable[Status]) -> tuple[int | None, list[str]]:
    """The finished tick count (summary or RUN_FINISHED status) and, if there is none or they differ, why."""
    status = summary.get("status")
    if status not in (None, "finished"):
        reason = str(summary.get("reason") or "")
        told = status == "faulted" or (reason and reason in map(str, summary.get("faults") or []))
        return None, [] if told else [f"the run did not finish (summary.json: {status!r} after "
                                      f"{summary.get('ticks', '?')} ticks: {reason or 'no reason given'})"]
    announced = {int(s.values[t.TICKS_KEY]) for s in statuses
                 if s.message == t.RUN_FINISHED and str(s.values.get(t.TICKS_KEY, "")).isdigit()}
    if status == "finished" and "ticks" in summary:
        announced.add(int(summary["ticks"]))
    if not announced:
        return None, ["the run's end is not recorded (no 'run finished' on /diagnostics, no finished summary.json)"]
    if len(announced) > 1:
        return max(announced), [f"the run's end was announced with different tick counts {sorted(announced)}"]
    return announced.pop(), []


def _period_ns(summary: Mapping[str, Any], record: RunRecord) -> int | None:
    """The lockstep tick period to check stamps against: T from the summary, else the first step; None in real time."""
    if summary.get("mode", "lockstep") != "lockstep":
        return None
    if summary.get("sample_time_s"):
        return int(round(float(summary["sample_time_s"]) * 1e9))
    stamps = np.unique(record.joint_states.stamp_ns)
    return int(stamps[1] - stamps[0]) if stamps.size > 1 else None


def per_tick_stamps(record: RunRecord) -> dict[str, IntArray | None]:
    """Relative per-tick topic name -> its recorded stamps (None where a record keeps no series of the topic)."""
    optional = [stage for stage, attr in _STAGE_SERIES.items() if getattr(record, attr, None) is not None]
    series: dict[str, Any] = {t.JOINT_STATES.name: record.joint_states, t.REFERENCE.name: record.reference}
    series.update({t.command_topic(axis): record.commands.get(axis) for axis in record.axis_names})
    series.update({getattr(t, attr.upper()).name: getattr(record, attr, None) for attr in _STAGE_SERIES.values()})
    empty = np.zeros(0, np.int64)
    return {name: (empty if series[name] is None else series[name].stamp_ns) if name in series else None
            for name in pipeline(record.axis_names, optional).per_tick_topics()}


def _gaps(record: RunRecord, ticks: int, period_ns: int | None, namespace: str) -> list[str]:
    """Per-tick topics that do not hold exactly one message per tick on contiguous stamps shared with joint_states."""
    problems: list[str] = []
    plant = np.unique(record.joint_states.stamp_ns)
    for name, stamps in per_tick_stamps(record).items():
        if stamps is not None:
            problems += _topic_gaps(t.qualify(namespace, name), stamps, ticks, period_ns, plant)
    return problems


def _topic_gaps(topic: str, stamps: IntArray, ticks: int, period_ns: int | None, plant: IntArray) -> list[str]:
    unique = np.unique(stamps)
    problems = [] if stamps.size == ticks else [f"{topic} holds {stamps.size} messages for {ticks} ticks"]
    if unique.size < stamps.size:
        problems.append(f"{topic} holds {stamps.size - unique.size} messages with a stamp seen before")
    steps = np.diff(unique)
    jumps = np.flatnonzero(steps != period_ns) if period_ns else np.zeros(0, np.int64)
    if jumps.size:
        problems.append(f"{topic} stamps are not contiguous: {jumps.size} jumps, the first from "
                        f"t = {unique[jumps[0]] * 1e-9:.6f} s to {unique[jumps[0] + 1] * 1e-9:.6f} s")
    elif unique.size and plant.size and not np.array_equal(unique, plant) and unique.size == plant.size:
        problems.append(f"{topic} stamps differ from joint_states' (first {unique[0] * 1e-9:.6f} s "
                        f"against {plant[0] * 1e-9:.6f} s)")
    return problems


def find_non_finite(record: RunRecord, namespace: str = t.DEFAULT_NAMESPACE) -> list[NonFinite]:
    """Non-finite positions, reference positions and commands in ``record``, with their first stamps."""
    checks: list[tuple[str, str, Any, Any]] = [
        (t.JOINT_STATES.name, "position", record.joint_states.stamp_ns, record.joint_states.position_m)]
    if record.reference is not None:
        checks.append((t.REFERENCE.name, "position_m", record.reference.stamp_ns, record.reference.position_m))
    checks += [(t.command_topic(a), "command", s.stamp_ns, s.command) for a, s in record.commands.items()]
    found = []
    for name, what, stamps, values in checks:
        values = np.asarray(values, dtype=float)
        bad = ~np.isfinite(values.reshape(values.shape[0], -1)).all(axis=1) if values.size else np.zeros(0, bool)
        if bad.any():
            found.append(NonFinite(t.qualify(namespace, name), what, int(bad.sum()), int(stamps[bad][0])))
    return found
