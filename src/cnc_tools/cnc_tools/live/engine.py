"""An engine run, live: every tick's messages to the live feed, the run paced to the wall clock.

:class:`EngineLive` is the engine's ``on_tick`` observer (:func:`cnc_tools.runs.engine.run_engine`). At tick k
it waits until ``k·T / rate`` wall seconds after the first tick (``rate`` 1: real time; the engine runs far faster
than that, so it mostly sleeps), then builds the tick's messages from the board (the same fields, from the same
floats, as the bag's, ``cnc_tools.bagio.record_bag``) and hands them to the :class:`~cnc_tools.live.feed.LiveFeed`:
``joint_states``, ``reference``, every ``servo/<axis>/command``, ``contour_error`` (with an estimator) and
``cutting_force`` (when the plant cuts); the feed override requested and applied come from the board. The
program's ``path`` goes out before the first tick.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import ConfigError
from cnc_contour_control.core.lockstep import split_ns
from cnc_contour_control.motion.interpolation import with_planning_tolerance
from cnc_tools.bagio.synthetic import path_message
from cnc_tools.live.feed import LiveFeed
from cnc_tools.runs.engine_stages import Board, EngineStage
from cnc_tools.runs.scenario import Scenario

#: Bounds of --live-rate (simulated seconds per wall second).
MIN_RATE, MAX_RATE = 0.01, 1000.0
#: Header frame of the suite's messages (as the bags').
FRAME_ID = "machine"


def check_rate(rate: float) -> float:
    """``rate`` if it is a usable pace, else an error naming the option, the bounds and the value."""
    if not MIN_RATE <= rate <= MAX_RATE:
        raise ConfigError(f"--live-rate must be in [{MIN_RATE:g}, {MAX_RATE:g}], got {rate}")
    return float(rate)


class EngineLive:
    """The engine's tick observer: paces the run and streams it (module docstring)."""

    def __init__(self, scenario: Scenario, feed: LiveFeed, rate: float = 1.0,
                 clock_ns: Callable[[], int] = time.monotonic_ns, wall_ns: Callable[[], int] = time.time_ns,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.scenario, self.feed, self.rate = scenario, feed, check_rate(rate)
        self.clock_ns, self.wall_ns, self.sleep = clock_ns, wall_ns, sleep
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

    def start(self) -> None:
        """The program's path (latched in a graph run), before the first tick."""
        program = with_planning_tolerance(self.scenario.program, self.scenario.interpolator)
        self._send(topics.PATH, path_message(program))

    def __call__(self, board: Board, stages: list[EngineStage]) -> None:
        """Tick ``board.tick``: wait for its wall time, then stream its messages."""
        self._pace(board.stamp_ns)
        stamp = self._header(board.stamp_ns)
        self._send(topics.JOINT_STATES, self.types[topics.JOINT_STATES.type_name](
            header=stamp, name=self.axes, position=np.array(board.position_m, float),
            velocity=np.array(board.velocity_m_s, float), effort=np.zeros(0)))
        self._send(topics.REFERENCE, self._reference(board, stages, stamp))
        self._commands(board, stages)
        if board.estimate is not None:
            self._send(topics.CONTOUR_ERROR, self._estimate(board.estimate, stamp))
        if self.cuts:
            self._send(topics.CUTTING_FORCE, self._wrench(board))
        self.feed.set_requested_override(board.stamp_ns, self._requested(board, stages), board.feed_override_ratio,
                                         self.wall_ns())

    @staticmethod
    def _requested(board: Board, stages: list[EngineStage]) -> float:
        """The override ratio requested at the tick: the scenario's schedule if it has one, else the board's."""
        live = getattr(next(s for s in stages if hasattr(s, "path_fields")), "live", None)
        return float(live.request(board.stamp_ns, board.feed_override_request) if live is not None
                     else board.feed_override_request)

    def _pace(self, stamp_ns: int) -> None:
        now = self.clock_ns()
        if self._start_ns is None:
            self._start_ns = now - int(stamp_ns / self.rate)
        due = self._start_ns + int(stamp_ns / self.rate)
        if due > now:
            self.sleep((due - now) * 1e-9)
        else:
            self.late_ticks += 1
            self.max_late_ns = max(self.max_late_ns, now - due)

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

    def _commands(self, board: Board, stages: list[EngineStage]) -> None:
        servo = next(s for s in stages if hasattr(s, "latest_parts"))
        make = self.types[topics.COMMAND.type_name]
        for config, parts in zip(self.scenario.servos, servo.latest_parts()):
            axis = config.axis_name
            self._send(topics.command_topic(axis), make(
                header=self._header(board.stamp_ns, axis), axis_name=axis, law=config.law,
                command_unit=config.command_unit, command=float(parts["command"]), feedback=float(parts["feedback"]),
                feedforward=float(parts["feedforward"]), compensation=float(parts["compensation"]),
                disturbance_estimate=float(parts["disturbance_estimate"]), saturated=bool(parts["saturated"]),
                error_m=float(parts["error_m"])))

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
