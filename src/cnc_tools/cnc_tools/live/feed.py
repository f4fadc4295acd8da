"""The suite's messages to the live server's channels, and the streams derived from them.

Every ROS message goes out as it came (CDR) on its topic under the suite's default namespace ``/cnc``
(``/cnc/joint_states``, ``/cnc/servo/x/command``, ...: the names an engine bag holds, so one layout fits every
run). From them, per window of stamp time (:data:`~cnc_tools.live.decimate.WINDOW_NS`):

- ``/live/contour_error/exact``: the exact contour error of every joint state (the scorer's
  ``Program.contour_distance``), JSON; ``/live/contour_error/exact/peaks`` its peak-keeping stream;
- ``/live/contour_error/estimated/peaks``: the estimator's ``contour_error`` (when the run has one);
- ``/live/servo/<axis>/peaks``: following error, command and saturation of each axis;
- ``/live/cutting_force/peaks``: the cutting force (when the plant cuts);
- ``/live/feed_override``, ``/live/xy``: the override requested and applied, the position and the reference,
  the last sample of each window;
- ``/live/log``: ``/diagnostics`` statuses as foxglove ``Log`` messages (and the feed's own notes);
- ``/live/scene``: the program's path and the tool's trail (``SceneUpdate``), at most :data:`SCENE_PERIOD_NS`.

Every message of one tick carries the caller's log time (wall ns when the tick reached the feed), which a client
subtracts from its own clock to measure the lag.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from foxglove.messages import Log, LogLevel, Timestamp

from cnc_contour_control.core import topics
from cnc_contour_control.core.lockstep import join_ns
from cnc_contour_control.motion.geometry import Program
from cnc_tools.bagio.path_message import program_from_path
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.live.decimate import WINDOW_NS, LastInWindow, PeakDecimator, window_runs
from cnc_tools.live.scene import Scene
from cnc_tools.live.server import LiveServer

#: Namespace of every ROS channel, whatever the run's own.
CHANNEL_NAMESPACE = topics.DEFAULT_NAMESPACE
#: Scene updates at most this often in stamp time (10 per simulated second).
SCENE_PERIOD_NS = 100_000_000
#: The exact contour error's peak stream.
EXACT_PEAKS = "/live/contour_error/exact/peaks"
#: Joint states held while the program (``path``) has not arrived yet.
MAX_PENDING = 10_000
#: ``diagnostic_msgs/DiagnosticStatus`` levels to foxglove log levels.
_LEVELS = {0: LogLevel.Info, 1: LogLevel.Warning, 2: LogLevel.Error, 3: LogLevel.Warning}


def _number_schema(title: str, **fields: str) -> dict[str, Any]:
    """A JSON schema ``cnc_live/<title>`` of an object with ``stamp_ns`` and the given fields (name -> JSON type)."""
    props = {"stamp_ns": {"type": "integer"}, **{name: {"type": kind} for name, kind in fields.items()}}
    return {"title": f"cnc_live/{title}", "type": "object", "properties": props, "required": sorted(props)}


EXACT_SCHEMA = _number_schema("ExactContourError", contour_error_um="number", segment_index="integer")
ESTIMATED_SCHEMA = _number_schema("EstimatedContourError", contour_error_um="number")
AXIS_SCHEMA = _number_schema("AxisError", following_error_um="number", command="number", saturated="boolean")
FORCE_SCHEMA = _number_schema("CuttingForce", force_n="number")
OVERRIDE_SCHEMA = _number_schema("FeedOverride", requested_ratio="number", applied_ratio="number")
XY_SCHEMA = _number_schema("PositionXY", x_mm="number", y_mm="number", ref_x_mm="number", ref_y_mm="number")
#: Peak streams derived from a topic, by its type: (channel, schema); ``{axis}`` from the command's topic.
DERIVED_PEAKS = {topics.COMMAND.type_name: ("/live/servo/{axis}/peaks", AXIS_SCHEMA),
                 topics.CONTOUR_ERROR.type_name: ("/live/contour_error/estimated/peaks", ESTIMATED_SCHEMA),
                 topics.CUTTING_FORCE.type_name: ("/live/cutting_force/peaks", FORCE_SCHEMA)}


def stamp_of(message: Any) -> int:
    """A message's header stamp, ns."""
    return join_ns(int(message.header.stamp.sec), int(message.header.stamp.nanosec))


class LiveFeed:
    """Fans the suite's messages out to a :class:`LiveServer`: as they are, and derived (module docstring).

    ``publish`` takes one message (its CDR and, if the caller has it, the decoded object); ``finish`` closes the
    open windows at the run's end.
    """

    def __init__(self, server: LiveServer, window_ns: int = WINDOW_NS) -> None:
        self.server, self.window_ns = server, int(window_ns)
        self.store = project_typestore()
        self.program: Program | None = None
        self.scene = Scene()
        self._next_scene_ns = 0
        self._pending: list[tuple[int, list[float]]] = []
        self._window: int | None = None
        self._peaks: dict[str, PeakDecimator[dict[str, Any]]] = {}
        self._xy = LastInWindow[dict[str, Any]](self.window_ns)
        self._override = LastInWindow[dict[str, Any]](self.window_ns)
        self._ref_mm: list[float] = [0.0, 0.0]
        self._override_now = {"requested_ratio": 1.0, "applied_ratio": 1.0}
        #: Called first by :meth:`finish` (a sender thread drains its batches).
        self.before_finish: list[Callable[[], None]] = []
        self._handlers: dict[str, Callable[[str, Any, int], None]] = {
            topics.PATH.name: self._on_path, topics.JOINT_STATES.name: self._on_joint_states,
            topics.REFERENCE.name: self._on_reference, topics.CONTOUR_ERROR.name: self._on_estimate,
            topics.FEED_OVERRIDE.name: self._on_feed_override, topics.CUTTING_FORCE.name: self._on_force,
            topics.DIAGNOSTICS.name: self._on_diagnostics}
        self.server.json_channel("/live/contour_error/exact", EXACT_SCHEMA)
        self.server.json_channel("/live/contour_error/exact/peaks", EXACT_SCHEMA)
        self.server.json_channel("/live/feed_override", OVERRIDE_SCHEMA)
        self.server.json_channel("/live/xy", XY_SCHEMA)
        self.server.typed_channel("/live/log", "Log")
        self.server.typed_channel("/live/scene", "SceneUpdate")

    # ------------------------------------------------------------------ input
    def advertise(self, name: str, type_name: str) -> None:
        """Offer topic ``name``'s channel before its first message (a client subscribes before the run starts)."""
        self.server.ros_channel(topics.qualify(CHANNEL_NAMESPACE, name), type_name)
        if type_name in DERIVED_PEAKS and name != topics.TOOL_POSITION.name:
            channel, schema = DERIVED_PEAKS[type_name]
            self.server.json_channel(channel.format(axis=name.split("/")[1] if "/" in name else ""), schema)

    def wants(self, name: str, type_name: str) -> bool:
        """True when a client subscribes to topic ``name``'s channel (else its CDR need not be made)."""
        return bool(self.server.ros_channel(topics.qualify(CHANNEL_NAMESPACE, name), type_name).has_sinks())

    def publish(self, name: str, type_name: str, cdr: bytes | memoryview | None, log_time_ns: int,
                message: Any = None) -> None:
        """One message of topic ``name`` (relative to the run's namespace, or ``/diagnostics``); ``cdr`` None:
        only its derived streams (no client wants the message itself, ``message`` holds it decoded)."""
        channel = self.server.ros_channel(topics.qualify(CHANNEL_NAMESPACE, name), type_name)
        if cdr is not None and channel.has_sinks():
            channel.log(bytes(cdr), log_time=log_time_ns)
        handler = self._handlers.get(name)
        if handler is None and name.startswith("servo/") and name.endswith("/command"):
            handler = self._on_command
        if handler is not None:
            handler(name, message if message is not None else self.store.deserialize_cdr(cdr or b"", type_name),
                    log_time_ns)

    def note(self, level: LogLevel, text: str, log_time_ns: int, name: str = "live") -> None:
        """A line on ``/live/log`` (a fault, the run's end)."""
        stamp = Timestamp(sec=log_time_ns // 1_000_000_000, nsec=log_time_ns % 1_000_000_000)
        self.server.typed_channel("/live/log", "Log").log(Log(timestamp=stamp, level=level, message=text, name=name),
                                                          log_time=log_time_ns)

    def finish(self, log_time_ns: int) -> None:
        """Close every open window (the run ended) and send the last scene."""
        for drain in self.before_finish:
            drain()
        self._flush_exact(log_time_ns)
        for topic, decimator in self._peaks.items():
            self._emit(topic, decimator.flush(), log_time_ns)
        self._emit("/live/xy", self._xy.flush(), log_time_ns)
        self._emit("/live/feed_override", self._override.flush(), log_time_ns)
        self._send_scene(self._next_scene_ns, log_time_ns)

    # ------------------------------------------------------------------ batches (the engine's sender thread)
    def log_rows(self, name: str, type_name: str, rows: Any, log_ns: Any) -> None:
        """Messages of topic ``name`` as CDR, one per row of ``rows`` (uint8), at log times ``log_ns``."""
        channel = self.server.ros_channel(topics.qualify(CHANNEL_NAMESPACE, name), type_name)
        for row, log_time_ns in zip(rows, log_ns.tolist()):
            channel.log(row.tobytes(), log_time=log_time_ns)

    def joint_states_many(self, stamps_ns: Any, log_ns: Any, position_m: Any, ref_position_m: Any) -> None:
        """A batch of joint states (B x axes) and the reference at the same ticks: the exact contour error (full
        rate and peaks), ``xy`` and the scene, as :meth:`publish` derives them one by one."""
        times, stamps = log_ns.tolist(), stamps_ns.tolist()
        if self.server.channels["/live/xy"].has_sinks():
            pos_mm, ref_mm = position_m[:, :2] * 1e3, ref_position_m[:, :2] * 1e3
            if pos_mm.shape[1] < 2:
                pos_mm, ref_mm = (np.pad(a, ((0, 0), (0, 2 - a.shape[1]))) for a in (pos_mm, ref_mm))
            self._emit_many("/live/xy", self._xy.push_many(stamps_ns, lambda i: {
                "stamp_ns": stamps[i], "x_mm": float(pos_mm[i, 0]), "y_mm": float(pos_mm[i, 1]),
                "ref_x_mm": float(ref_mm[i, 0]), "ref_y_mm": float(ref_mm[i, 1])}), times)
        else:
            self._xy.flush()
        self._trail_many(stamps_ns, log_ns, position_m)
        exact = self.server.channels["/live/contour_error/exact"]
        if self.program is None or not (exact.has_sinks() or self.server.channels[EXACT_PEAKS].has_sinks()):
            self._peaks.pop(EXACT_PEAKS, None)
            return
        error_m, index = self.program.contour_distance(np.asarray(position_m, float))
        error_um, segments = (error_m * 1e6).tolist(), index.tolist()
        if exact.has_sinks():
            for k, stamp_ns in enumerate(stamps):
                exact.log({"stamp_ns": stamp_ns, "contour_error_um": error_um[k], "segment_index": int(segments[k])},
                          log_time=times[k])
        self.peaks_many(EXACT_PEAKS, EXACT_SCHEMA, stamps_ns, log_ns, error_m * 1e6,
                        lambda i: {"stamp_ns": stamps[i], "contour_error_um": error_um[i],
                                   "segment_index": int(segments[i])})

    def _trail_many(self, stamps_ns: Any, log_ns: Any, position_m: Any) -> None:
        """The tool's trail (a point per window) and the scene every :data:`SCENE_PERIOD_NS`."""
        stamps = stamps_ns.tolist()
        for start, _ in window_runs(stamps_ns, self.window_ns):
            window = stamps[start] // self.window_ns
            if self._window is not None and window != self._window:
                self.scene.add_tool(position_m[start].tolist())
            self._window = window
        if stamps[-1] >= self._next_scene_ns:
            k = int(np.searchsorted(stamps_ns, self._next_scene_ns))
            self._send_scene(stamps[k], int(log_ns[k]))

    def watched(self) -> bool:
        """True when a client subscribes to any channel."""
        return any(channel.has_sinks() for channel in self.server.channels.values())

    def unwatched_many(self, stamps_ns: Any, log_ns: Any, position_m: Any, requested: float, applied: float) -> None:
        """A batch while no client subscribes to anything: only the trail and the override's state go on, and no
        window is kept (a viewer's first window starts when it joins)."""
        self._trail_many(stamps_ns, log_ns, position_m)
        self._override_now.update(requested_ratio=requested, applied_ratio=applied)
        for decimator in self._peaks.values():
            decimator.flush()
        self._xy.flush()
        self._override.flush()

    def peaks_many(self, topic: str, schema: dict[str, Any], stamps_ns: Any, log_ns: Any, values: Any,
                   make: Callable[[int], dict[str, Any]]) -> None:
        """A batch of one peak stream's samples: ``values`` judged, ``make(i)`` the message of sample i."""
        decimator = self._peaks.get(topic)
        if decimator is None:
            decimator = self._peaks[topic] = PeakDecimator(self.window_ns)
        if not self.server.json_channel(topic, schema).has_sinks():
            decimator.flush()  # nobody watches: no window is kept (a viewer's first window starts when it joins)
            return
        self._emit_many(topic, decimator.push_many(stamps_ns, values, make), log_ns.tolist())

    def overrides_many(self, stamps_ns: Any, log_ns: Any, requested: Any, applied: Any) -> None:
        """A batch of the override requested and applied (the engine's board)."""
        stamps, req, app = stamps_ns.tolist(), requested.tolist(), applied.tolist()
        self._override_now.update(requested_ratio=req[-1], applied_ratio=app[-1])
        if not self.server.channels["/live/feed_override"].has_sinks():
            self._override.flush()
            return
        kept = self._override.push_many(stamps_ns, lambda i: {"stamp_ns": stamps[i], "requested_ratio": req[i],
                                                              "applied_ratio": app[i]})
        self._emit_many("/live/feed_override", kept, log_ns.tolist())

    def _emit_many(self, topic: str, kept: list[tuple[dict[str, Any], int]], times: list[int]) -> None:
        channel = self.server.channels[topic]
        if kept and channel.has_sinks():
            for sample, k in kept:
                channel.log(sample, log_time=times[k])

    # ------------------------------------------------------------------ handlers
    def _on_path(self, name: str, message: Any, log_time_ns: int) -> None:
        self.program = program_from_path(message)
        self.scene.set_program(self.program)
        self._send_scene(0, log_time_ns)

    def _on_joint_states(self, name: str, message: Any, log_time_ns: int) -> None:
        stamp_ns, position = stamp_of(message), [float(v) for v in message.position]
        window = stamp_ns // self.window_ns
        if self._window is not None and window != self._window:
            self._flush_exact(log_time_ns)
            self.scene.add_tool(position)
        self._window = window
        self._pending.append((stamp_ns, position))
        del self._pending[:-MAX_PENDING]
        xy = {"stamp_ns": stamp_ns, "x_mm": position[0] * 1e3, "y_mm": position[1] * 1e3 if len(position) > 1
              else 0.0, "ref_x_mm": self._ref_mm[0], "ref_y_mm": self._ref_mm[1]}
        self._emit("/live/xy", self._xy.push(stamp_ns, xy), log_time_ns)
        if stamp_ns >= self._next_scene_ns:
            self._send_scene(stamp_ns, log_time_ns)

    def _on_reference(self, name: str, message: Any, log_time_ns: int) -> None:
        ref = [float(v) * 1e3 for v in message.position_m]
        self._ref_mm = ref[:2] + [0.0] * max(0, 2 - len(ref))
        self._override_now["applied_ratio"] = float(message.feed_override_ratio)
        self._push_override(stamp_of(message), log_time_ns)

    def _on_feed_override(self, name: str, message: Any, log_time_ns: int) -> None:
        self._override_now["requested_ratio"] = float(message.requested_ratio)
        self._push_override(stamp_of(message), log_time_ns)

    def _push_override(self, stamp_ns: int, log_time_ns: int) -> None:
        sample = {"stamp_ns": stamp_ns, **self._override_now}
        self._emit("/live/feed_override", self._override.push(stamp_ns, sample), log_time_ns)

    def _on_command(self, name: str, message: Any, log_time_ns: int) -> None:
        stamp_ns = stamp_of(message)
        sample = {"stamp_ns": stamp_ns, "following_error_um": float(message.error_m) * 1e6,
                  "command": float(message.command), "saturated": bool(message.saturated)}
        self._peak(f"/live/servo/{message.axis_name}/peaks", AXIS_SCHEMA, stamp_ns,
                   sample["following_error_um"], sample, log_time_ns)

    def _on_estimate(self, name: str, message: Any, log_time_ns: int) -> None:
        stamp_ns = stamp_of(message)
        sample = {"stamp_ns": stamp_ns, "contour_error_um": float(message.contour_error_m) * 1e6}
        self._peak("/live/contour_error/estimated/peaks", ESTIMATED_SCHEMA, stamp_ns, sample["contour_error_um"],
                   sample, log_time_ns)

    def _on_force(self, name: str, message: Any, log_time_ns: int) -> None:
        stamp_ns = stamp_of(message)
        sample = {"stamp_ns": stamp_ns, "force_n": float(message.wrench.force.x)}
        self._peak("/live/cutting_force/peaks", FORCE_SCHEMA, stamp_ns, sample["force_n"], sample, log_time_ns)

    def _on_diagnostics(self, name: str, message: Any, log_time_ns: int) -> None:
        for status in message.status:
            self.note(_LEVELS.get(int(status.level), LogLevel.Unknown), str(status.message), log_time_ns,
                      name=str(status.name))

    # ------------------------------------------------------------------ derived streams
    def _flush_exact(self, log_time_ns: int) -> None:
        """The exact contour error of the held joint states (once the program is known)."""
        if self.program is None or not self._pending:
            return
        stamps = [s for s, _ in self._pending]
        error_m, index = self.program.contour_distance(np.array([p for _, p in self._pending], float))
        self._pending = []
        channel = self.server.channels["/live/contour_error/exact"]
        full_rate = channel.has_sinks()
        for stamp_ns, error, segment in zip(stamps, error_m.tolist(), index.tolist()):
            sample = {"stamp_ns": stamp_ns, "contour_error_um": error * 1e6, "segment_index": int(segment)}
            if full_rate:
                channel.log(sample, log_time=log_time_ns)
            self._peak("/live/contour_error/exact/peaks", EXACT_SCHEMA, stamp_ns, sample["contour_error_um"],
                       sample, log_time_ns)

    def _peak(self, topic: str, schema: dict[str, Any], stamp_ns: int, value: float, sample: dict[str, Any],
              log_time_ns: int) -> None:
        decimator = self._peaks.get(topic)
        if decimator is None:
            self.server.json_channel(topic, schema)
            decimator = self._peaks[topic] = PeakDecimator(self.window_ns)
        self._emit(topic, decimator.push(stamp_ns, value, sample), log_time_ns)

    def _emit(self, topic: str, samples: list[dict[str, Any]], log_time_ns: int) -> None:
        channel = self.server.channels[topic]
        if samples and channel.has_sinks():
            for sample in samples:
                channel.log(sample, log_time=log_time_ns)

    def _send_scene(self, stamp_ns: int, log_time_ns: int) -> None:
        channel = self.server.typed_channel("/live/scene", "SceneUpdate")
        self._next_scene_ns = stamp_ns + SCENE_PERIOD_NS
        if (not self.scene.path and not self.scene.trail) or not channel.has_sinks():
            return
        channel.log(self.scene.update(stamp_ns),
                                                                    log_time=log_time_ns)
