"""An engine run, live: every tick's messages to the live feed, the run paced to the wall clock.

:class:`EngineLive` is the engine's ``on_tick`` observer (:func:`cnc_tools.runs.engine.run_engine`). Tick k runs
once it is at most :data:`AHEAD_NS` ahead of ``k·T / rate`` wall seconds after the first tick (``rate`` 1: real
time; the engine runs far faster than that, so it runs a burst of ticks and sleeps). The engine's thread only notes
each tick's values from the board; before each sleep (or every :data:`SEND_PERIOD_NS` when it does not sleep) the
batch goes to a sender thread, which writes the messages of the whole batch (the same fields, from the same floats,
as the bag's, ``cnc_tools.bagio.record_bag``; CDR by :class:`~cnc_tools.live.cdr.CdrTemplate`) for the subscribed
channels and steps the derived streams of the :class:`~cnc_tools.live.feed.LiveFeed`: ``joint_states``,
``reference``, every ``servo/<axis>/command``, ``contour_error`` (with an estimator) and ``cutting_force`` (when
the plant cuts); the feed override requested and applied come from the board. The program's ``path`` goes out
before the first tick; the feed's ``finish`` sends what is left and stops the thread.
"""
from __future__ import annotations

import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_contour_control.core.lockstep import NS_PER_S, split_ns
from cnc_contour_control.motion.interpolation import with_planning_tolerance
from cnc_tools.bagio.synthetic import path_message
from cnc_tools.live.cdr import CdrTemplate
from cnc_tools.live.feed import AXIS_SCHEMA, ESTIMATED_SCHEMA, FORCE_SCHEMA, LiveFeed
from cnc_tools.runs.engine import tick_count
from cnc_tools.runs.engine_stages import Board, EngineStage, ServoStage
from cnc_tools.runs.scenario import Scenario

#: Bounds of --live-rate (simulated seconds per wall second).
MIN_RATE, MAX_RATE = 0.01, 1000.0
#: Header frame of the suite's messages (as the bags').
FRAME_ID = "machine"
#: Wall time between two batches handed to the sender thread [ns] when the engine does not sleep (late, or unpaced):
#: a tick waits at most this before it is sent.
SEND_PERIOD_NS = 10_000_000
#: A tick runs at once while it is at most this ahead of its wall time [ns], so the engine's thread sleeps once
#: per burst of ticks, not every tick (a sleep and its wake-up cost more CPU than a tick); the burst's batch
#: leaves before the sleep.
AHEAD_NS = 10_000_000
#: Hand-off times kept for statistics (the last ~100 s at the default period).
LAGS_KEPT = 10_000
#: A servo's command parts in a batch row (``AxisCommand`` fields, as ``latest_parts`` names them).
COMMAND_PARTS = ("command", "feedback", "feedforward", "compensation", "disturbance_estimate", "saturated", "error_m")
#: Batches queued for the sender before the engine's thread waits for it (a stalled sender bounds the memory).
MAX_QUEUED = 1000


def check_rate(rate: float) -> float:
    """``rate`` if it is a usable pace, else an error naming the option, the bounds and the value."""
    if not MIN_RATE <= rate <= MAX_RATE:
        raise ConfigError(f"--live-rate must be in [{MIN_RATE:g}, {MAX_RATE:g}], got {rate}")
    return float(rate)


@dataclass
class _Batch:
    """Ticks noted by the engine's thread: stamps, wall times they reached the feed, values (one row per tick: axes x
    (position, velocity, reference position, velocity, acceleration), path fields, overrides, force, servo parts),
    and the estimates (row index, fields)."""

    stamps_ns: list[int] = field(default_factory=list)
    log_ns: list[int] = field(default_factory=list)
    rows: list[list[float]] = field(default_factory=list)
    estimates: list[tuple[int, list[float]]] = field(default_factory=list)


class _Sender:
    """A thread that runs ``work`` on each batch put, in order; an error it meets is raised by the next put or close."""

    def __init__(self, work: Callable[[_Batch], None]) -> None:
        self.work = work
        self.queue: queue.Queue[_Batch | None] = queue.Queue(MAX_QUEUED)
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="live-sender", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        """Work batch after batch; batches that queued while it worked are merged into one (a sender behind the
        engine catches up with fewer, larger numpy passes)."""
        closing = False
        while not closing and (batch := self.queue.get()) is not None:
            while not self.queue.empty() and not closing:
                more = self.queue.get_nowait()
                closing = more is None
                if more is not None:
                    batch.estimates += [(k + len(batch.rows), values) for k, values in more.estimates]
                    batch.stamps_ns += more.stamps_ns
                    batch.log_ns += more.log_ns
                    batch.rows += more.rows
            if self.error is None:
                try:
                    self.work(batch)
                except BaseException as err:  # handed to the engine's thread, which raises it
                    self.error = err

    def _raise(self) -> None:
        if self.error is not None:
            raise CncError(f"live sender failed: {self.error}") from self.error

    def put(self, batch: _Batch) -> None:
        self._raise()
        self.queue.put(batch)

    def close(self) -> None:
        if self.thread.is_alive():
            self.queue.put(None)
            self.thread.join()
        self._raise()


def _axis_samples(stamps: list[int], parts: Any) -> Callable[[int], dict[str, Any]]:
    """The ``/live/servo/<axis>/peaks`` message of batch sample i (``parts``: rows of :data:`COMMAND_PARTS`)."""
    error_um, command, saturated = (parts[:, 6] * 1e6).tolist(), parts[:, 0].tolist(), parts[:, 5].tolist()
    return lambda i: {"stamp_ns": stamps[i], "following_error_um": error_um[i], "command": command[i],
                      "saturated": bool(saturated[i])}


class EngineLive:
    """The engine's tick observer: paces the run and streams it (module docstring)."""

    def __init__(self, scenario: Scenario, feed: LiveFeed, rate: float = 1.0,
                 clock_ns: Callable[[], int] = time.monotonic_ns, wall_ns: Callable[[], int] = time.time_ns,
                 sleep: Callable[[float], None] = time.sleep, send_period_ns: int = SEND_PERIOD_NS,
                 ahead_ns: int = AHEAD_NS) -> None:
        self.scenario, self.feed, self.rate = scenario, feed, check_rate(rate)
        self.clock_ns, self.wall_ns, self.sleep = clock_ns, wall_ns, sleep
        self.send_period_ns, self.ahead_ns = int(send_period_ns), int(ahead_ns)
        self.types = feed.store.types
        self.axes = list(scenario.axes)
        per_tick = scenario.pipeline().per_tick_topics()
        self.cuts = topics.CUTTING_FORCE.name in per_tick
        for name in (topics.PATH.name, topics.JOINT_STATES.name, topics.REFERENCE.name, topics.CONTOUR_ERROR.name,
                     topics.CUTTING_FORCE.name, *map(topics.command_topic, self.axes)):
            if name == topics.PATH.name or name in per_tick:
                feed.advertise(name, topics.type_of(name, self.axes))
        self._start_ns: int | None = None
        #: Ticks reached after their due wall time, and the latest of them behind it [ns] (the pacing's record).
        self.late_ticks, self.max_late_ns = 0, 0
        self._batch = _Batch()
        self._last_tick = tick_count(scenario) - 1  # its batch leaves at once (the bag is written before finish)
        self._templates: dict[str, CdrTemplate] = {}
        #: Per batch sent (the last :data:`LAGS_KEPT`): wall time from its first tick to its last message handed to
        #: the server [ns] (the feed's share of a viewer's lag).
        self.handoff_ns: deque[int] = deque(maxlen=LAGS_KEPT)
        self._sender = _Sender(self._send_batch)
        feed.before_finish.append(self.close)

    def start(self) -> None:
        """The program's path (latched in a graph run), before the first tick."""
        program = with_planning_tolerance(self.scenario.program, self.scenario.interpolator)
        self._send(topics.PATH, path_message(program))

    def __call__(self, board: Board, stages: list[EngineStage]) -> None:
        """Tick ``board.tick``: wait for its wall time, note its values; before a sleep, or once its first tick is
        ``send_period_ns`` old, the batch goes to the sender thread (the engine's thread builds and sends nothing)."""
        if not self._templates:  # before the pacing starts its clock: rosbags compiles a serialiser per type
            self._make_templates(board, stages)
        self._pace(board.stamp_ns)
        now_ns = self.wall_ns()
        batch = self._batch
        batch.stamps_ns.append(board.stamp_ns)
        batch.log_ns.append(now_ns)
        row = [*board.position_m, *board.velocity_m_s, *board.ref_position_m, *board.ref_velocity_m_s,
               *board.ref_acceleration_m_s2, *self._interpolator.path_fields(board.tick),
               board.feed_override_ratio, self._requested(board), board.cutting_force_n]
        row.extend(self._servo.latest_flat())
        batch.rows.append(row)
        estimate = board.estimate
        if estimate is not None:
            if topics.CONTOUR_ERROR.name not in self._templates:
                self._estimate_template(board)
            batch.estimates.append((len(batch.rows) - 1, [
                estimate.contour_error_m, *estimate.tracking_error_m, estimate.segment_index, estimate.angle_rad,
                *estimate.point_a_m, *estimate.point_b_m, estimate.window_size, estimate.steps]))
        if now_ns - batch.log_ns[0] >= self.send_period_ns or board.tick == self._last_tick:
            self._hand_off()

    def _hand_off(self) -> None:
        self._sender.put(self._batch)
        self._batch = _Batch()

    def close(self) -> None:
        """Send what is left and stop the sender thread (the feed's ``finish`` calls it); an error the sender met is
        raised here."""
        if self._batch.rows:
            self._sender.put(self._batch)
            self._batch = _Batch()
        self._sender.close()

    def _make_templates(self, board: Board, stages: list[EngineStage]) -> None:
        """The CDR templates of the run's messages, from the first tick's messages (their strings and lengths)."""
        self._interpolator = next(s for s in stages if hasattr(s, "path_fields"))
        self._servo = next(s for s in stages if isinstance(s, ServoStage))
        order = tuple(self._servo.latest_parts()[0])
        if order != COMMAND_PARTS:
            raise CncError(f"live: the servo stage's parts are {order}, the batch rows expect {COMMAND_PARTS}")
        self._live_request = getattr(self._interpolator, "live", None)
        stamp = self._header(board.stamp_ns)
        store, make = self.feed.store, self.types
        self._templates[topics.JOINT_STATES.name] = CdrTemplate(store, topics.JOINT_STATES.type_name, make[
            topics.JOINT_STATES.type_name](header=stamp, name=self.axes, position=np.array(board.position_m, float),
                                           velocity=np.array(board.velocity_m_s, float), effort=np.zeros(0)))
        self._templates[topics.REFERENCE.name] = CdrTemplate(store, topics.REFERENCE.type_name,
                                                             self._reference(board, stages, stamp))
        for name, message in self._commands(board, stages):
            self._templates[name] = CdrTemplate(store, topics.COMMAND.type_name, message)
        if self.cuts:
            self._templates[topics.CUTTING_FORCE.name] = CdrTemplate(store, topics.CUTTING_FORCE.type_name,
                                                                     self._wrench(board))

        if board.estimate is not None:
            self._estimate_template(board)

    def _estimate_template(self, board: Board) -> None:
        self._templates[topics.CONTOUR_ERROR.name] = CdrTemplate(
            self.feed.store, topics.CONTOUR_ERROR.type_name, self._estimate(board.estimate,
                                                                            self._header(board.stamp_ns)))

    def _requested(self, board: Board) -> float:
        """The override ratio requested at the tick: the scenario's schedule if it has one, else the board's."""
        live = self._live_request
        return float(live.request(board.stamp_ns, board.feed_override_request) if live is not None
                     else board.feed_override_request)

    def _pace(self, stamp_ns: int) -> None:
        now = self.clock_ns()
        if self._start_ns is None:
            self._start_ns = now - int(stamp_ns / self.rate)
        due = self._start_ns + int(stamp_ns / self.rate)
        if due - now > self.ahead_ns:
            if self._batch.rows:  # the ticks run so far leave now, not after the sleep
                self._hand_off()
            self.sleep((due - now) * 1e-9)
        elif due < now:
            self.late_ticks += 1
            self.max_late_ns = max(self.max_late_ns, now - due)

    def _send_batch(self, batch: _Batch) -> None:
        """The sender thread's work for one batch: CDR for the subscribed ROS channels (numpy, the whole batch at
        once), then the derived streams."""
        feed, n = self.feed, len(self.axes)
        stamps_ns, log_ns = np.array(batch.stamps_ns, np.int64), np.array(batch.log_ns, np.int64)
        v = np.array(batch.rows, float)
        rows = len(v)
        sec, nanosec = np.divmod(stamps_ns, NS_PER_S)
        header = {"header.stamp.sec": sec, "header.stamp.nanosec": nanosec}
        position, ref = v[:, 0:n], v[:, 2 * n:3 * n]
        base = 5 * n  # path length, segment, feed, done, applied, requested, force
        if not feed.watched():
            feed.unwatched_many(stamps_ns, log_ns, position, float(v[-1, base + 5]), float(v[-1, base + 4]))
            self.handoff_ns.append(time.time_ns() - batch.log_ns[0])
            return
        self._log(topics.JOINT_STATES.name, rows, log_ns, {**header, "position": position, "velocity": v[:, n:2 * n]})
        self._log(topics.REFERENCE.name, rows, log_ns, {
            **header, "position_m": ref, "velocity_m_s": v[:, 3 * n:4 * n], "acceleration_m_s2": v[:, 4 * n:base],
            "path_length_m": v[:, base], "segment_index": v[:, base + 1], "feed_m_s": v[:, base + 2],
            "programmed_feed_m_s": v[:, base + 2], "done": v[:, base + 3], "feed_override_ratio": v[:, base + 4]})
        feed.joint_states_many(stamps_ns, log_ns, position, ref)
        feed.overrides_many(stamps_ns, log_ns, v[:, base + 5], v[:, base + 4])
        stamps = batch.stamps_ns
        for j, axis in enumerate(config.axis_name for config in self.scenario.servos):
            parts = v[:, base + 7 + j * len(COMMAND_PARTS):base + 7 + (j + 1) * len(COMMAND_PARTS)]
            self._log(topics.command_topic(axis), rows, log_ns,
                      {**header, **{name: parts[:, k] for k, name in enumerate(COMMAND_PARTS)}})
            feed.peaks_many(f"/live/servo/{axis}/peaks", AXIS_SCHEMA, stamps_ns, log_ns, parts[:, 6] * 1e6,
                            _axis_samples(stamps, parts))
        if self.cuts:
            force = v[:, base + 6]
            self._log(topics.CUTTING_FORCE.name, rows, log_ns, {**header, "wrench.force.x": force})
            feed.peaks_many("/live/cutting_force/peaks", FORCE_SCHEMA, stamps_ns, log_ns, force,
                            lambda i: {"stamp_ns": stamps[i], "force_n": float(force[i])})
        if batch.estimates:
            self._send_estimates(batch, stamps_ns, log_ns)
        self.handoff_ns.append(time.time_ns() - batch.log_ns[0])

    def _send_estimates(self, batch: _Batch, stamps_ns: Any, log_ns: Any) -> None:
        index = np.array([k for k, _ in batch.estimates], np.int64)
        e = np.array([values for _, values in batch.estimates], float)
        stamps, logs, n = stamps_ns[index], log_ns[index], len(self.axes)
        name = topics.CONTOUR_ERROR.name
        if self.feed.wants(name, topics.CONTOUR_ERROR.type_name):
            sec, nanosec = np.divmod(stamps, NS_PER_S)
            t = 1 + n
            self._log(name, len(e), logs, {
                "header.stamp.sec": sec, "header.stamp.nanosec": nanosec, "contour_error_m": e[:, 0],
                "tracking_error_m": e[:, 1:t], "segment_index": e[:, t], "angle_rad": e[:, t + 1],
                "point_a_m": e[:, t + 2:t + 2 + n], "point_b_m": e[:, t + 2 + n:t + 2 + 2 * n],
                "window_size": e[:, t + 2 + 2 * n], "window_steps": e[:, t + 3 + 2 * n]})
        error_um, at = e[:, 0] * 1e6, stamps.tolist()
        self.feed.peaks_many("/live/contour_error/estimated/peaks", ESTIMATED_SCHEMA, stamps, logs, error_um,
                             lambda i: {"stamp_ns": at[i], "contour_error_um": float(error_um[i])})

    def _log(self, name: str, rows: int, log_ns: Any, values: dict[str, Any]) -> None:
        template = self._templates[name]
        if self.feed.wants(name, template.type_name):
            self.feed.log_rows(name, template.type_name, template.fill(rows, values), log_ns)

    def _header(self, stamp_ns: int, frame_id: str = FRAME_ID) -> Any:
        sec, nanosec = split_ns(stamp_ns)
        return self.types["std_msgs/msg/Header"](stamp=self.types["builtin_interfaces/msg/Time"](
            sec=sec, nanosec=nanosec), frame_id=frame_id)

    def _send(self, topic: topics.Topic | str, message: Any) -> None:
        name = topic if isinstance(topic, str) else topic.name
        type_name = topics.COMMAND.type_name if isinstance(topic, str) else topic.type_name
        cdr = self.feed.store.serialize_cdr(message, type_name) if self.feed.wants(name, type_name) else None
        self.feed.publish(name, type_name, cdr, self.wall_ns(), message)

    def _reference(self, board: Board, stages: list[EngineStage], header: Any) -> Any:
        interpolator = next(s for s in stages if hasattr(s, "path_fields"))
        path_length_m, segment, feed_m_s, done = interpolator.path_fields(board.tick)
        return self.types[topics.REFERENCE.type_name](
            header=header, axis_names=self.axes, position_m=np.array(board.ref_position_m, float),
            velocity_m_s=np.array(board.ref_velocity_m_s, float),
            acceleration_m_s2=np.array(board.ref_acceleration_m_s2, float), path_length_m=path_length_m,
            segment_index=segment, feed_m_s=feed_m_s, programmed_feed_m_s=feed_m_s,
            feed_override_ratio=float(board.feed_override_ratio), done=done)

    def _commands(self, board: Board, stages: list[EngineStage]) -> list[tuple[str, Any]]:
        servo = next(s for s in stages if hasattr(s, "latest_parts"))
        make = self.types[topics.COMMAND.type_name]
        messages = []
        for config, parts in zip(self.scenario.servos, servo.latest_parts()):
            axis = config.axis_name
            messages.append((topics.command_topic(axis), make(
                header=self._header(board.stamp_ns, axis), axis_name=axis, law=config.law,
                command_unit=config.command_unit, command=float(parts["command"]), feedback=float(parts["feedback"]),
                feedforward=float(parts["feedforward"]), compensation=float(parts["compensation"]),
                disturbance_estimate=float(parts["disturbance_estimate"]), saturated=bool(parts["saturated"]),
                error_m=float(parts["error_m"]))))
        return messages

    def _estimate(self, e: Any, header: Any) -> Any:
        method = self.scenario.estimator.method if self.scenario.estimator is not None else ""
        return self.types[topics.CONTOUR_ERROR.type_name](
            header=header, axis_names=self.axes, contour_error_m=float(e.contour_error_m),
            tracking_error_m=np.array(e.tracking_error_m, float), segment_index=int(e.segment_index),
            angle_rad=float(e.angle_rad), point_a_m=np.array(e.point_a_m, float),
            point_b_m=np.array(e.point_b_m, float), window_size=int(e.window_size), window_steps=int(e.steps),
            method=method)

    def _wrench(self, board: Board) -> Any:
        vector, wrench = self.types["geometry_msgs/msg/Vector3"], self.types["geometry_msgs/msg/Wrench"]
        return self.types[topics.CUTTING_FORCE.type_name](
            header=self._header(board.stamp_ns, "tool"), wrench=wrench(
                force=vector(float(board.cutting_force_n), 0.0, 0.0), torque=vector(0.0, 0.0, 0.0)))
