"""The viewer talks back to a run: parameters and client publish (foxglove-sdk's ``Parameters`` and
``ClientPublish`` capabilities), ROS-free.

:class:`Talkback` is the live server's listener. Parameters: every axis's servo gains as
``servo_<axis>.gains.<field>`` (the servo node's ``gains.*``) and, with a neural compensator, its learning rate
``compensator.params.eta`` (the compensator node's ``params.eta``). Client publish (JSON, or CDR with the suite's
ROS 2 definitions) on the topics an operator's tools use: ``/cnc/feed_override`` (``FeedOverride``: the ratio
:func:`message_ratio` takes, refused as the interpolator's inbox refuses it: not finite or outside
[0, max_ratio]), ``/cnc/feed_hold`` (``std_msgs/Bool``: true holds the feed, false resumes at the last ratio
asked), ``/cnc/estop`` and ``/cnc/enable`` (``std_msgs/Bool``). Every refusal is a warning status naming the value
and the bound; a refused parameter keeps its value.

:class:`EngineTalkback` (``run --engine --live``) checks a parameter as the node would (the descriptor's range in
rclpy's words, :func:`range_refusal`, then the config the node's on-set callback builds) and applies what it
accepts at the engine's next tick, on the engine's thread (``ServoController.retune``: the law's state stays); an
e-stop ends the run as a fault (verdict ``faulted``); an engine has no enable, so false is refused.
:class:`GraphTalkback` (``run --live``, the ``live`` node) hands the requests to a :class:`GraphBus` (``live/ros.py``
``RosBus``): the nodes' parameter services, whose answer is the viewer's, the run's ``feed_override`` and ``estop``
topics and every node's ``~/enable``.
"""
from __future__ import annotations

import json
import math
import queue
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol

from foxglove.websocket import (
    Capability,
    Client,
    ClientChannel,
    Parameter,
    ServerListener,
    StatusLevel,
)

from cnc_contour_control.axis.servo import ServoConfig
from cnc_contour_control.compensators import compensator_config_class
from cnc_contour_control.core.errors import CncError, FaultError
from cnc_contour_control.core.params import config_values, flat_specs
from cnc_contour_control.graph.cross_axis import CompensatorSettings
from cnc_contour_control.laws import law_config_class
from cnc_contour_control.motion.feed_override import OverrideInbox, message_ratio
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.live.engine import EngineLive
from cnc_tools.live.feed import LiveFeed
from cnc_tools.runs.engine_cross_axis import CompensatorStage
from cnc_tools.runs.engine_stages import Board, EngineStage, ServoStage
from cnc_tools.runs.scenario import Scenario

if TYPE_CHECKING:
    from cnc_tools.live.server import LiveServer

#: Topics a client may publish on, and their ROS 2 types (JSON carries the same fields).
CLIENT_TOPICS = {"/cnc/feed_override": "cnc_contour_interfaces/msg/FeedOverride",
                 "/cnc/feed_hold": "std_msgs/msg/Bool", "/cnc/estop": "std_msgs/msg/Bool",
                 "/cnc/enable": "std_msgs/msg/Bool"}
#: rclpy's tolerance at a range's ends (``Node.PARAM_REL_TOL``).
RANGE_REL_TOL = 1e-6
#: The compensator whose learning rate is a parameter, and that parameter.
LEARNING_RATE = "compensator.params.eta"

Action = Callable[[Board, list[EngineStage]], None]


class Refused(CncError):
    """A request the run does not take; its text goes to the client."""


@dataclass(frozen=True)
class _Gain:
    """A servo gain as a parameter: the axis's index and the law's field."""

    axis: int
    field: str


def range_refusal(name: str, low: float | None, high: float | None, value: float | int) -> str | None:
    """Why the node's parameter ``name`` refuses ``value`` by its descriptor's range, in rclpy's words (its
    ``FloatingPointRange`` / ``IntegerRange`` check runs before the node's own callback), else None."""
    low_v, high_v = -math.inf if low is None else low, math.inf if high is None else high
    if isinstance(value, int) and not isinstance(value, bool):
        low_v, high_v = (-(2**63) if low is None else math.ceil(low)), (2**63 - 1 if high is None else math.floor(high))
        inside = low_v <= value <= high_v
        return None if inside else f"Parameter {name} out of range. Min: {low_v}, Max: {high_v}, value: {value}"
    edge = any(math.isclose(value, v, rel_tol=RANGE_REL_TOL) for v in (low_v, high_v))
    if edge or low_v < value < high_v:
        return None
    return f"Parameter {name} out of range Min: {float(low_v)}, Max: {float(high_v)}, value: {value}"


def decode(encoding: str, type_name: str, data: bytes) -> dict[str, Any]:
    """A client's message as its fields (JSON object, or CDR of ``type_name``)."""
    if encoding == "json":
        try:
            fields = json.loads(data)
        except ValueError as err:
            raise Refused(f"{type_name}: not JSON ({err})") from err
        if not isinstance(fields, dict):
            raise Refused(f"{type_name}: a JSON object is expected, got {fields!r}")
        return fields
    if encoding == "cdr":
        try:
            message: Any = project_typestore().deserialize_cdr(bytes(data), type_name)
        except Exception as err:  # rosbags raises several kinds on a short or foreign buffer
            raise Refused(f"{type_name}: not the CDR of the type ({err})") from err
        return {name: getattr(message, name) for name in message.__dataclass_fields__}
    raise Refused(f"message encoding must be json or cdr, got {encoding!r}")


def number(fields: dict[str, Any], name: str, default: float | None = None) -> float:
    """Field ``name`` as a float (``default`` when absent); anything else is refused naming it."""
    value = fields.get(name, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise Refused(f"{name} must be a number, got {value!r}")
    return float(value)


def flag(fields: dict[str, Any]) -> bool:
    """``std_msgs/Bool``'s ``data``; anything but a boolean is refused."""
    value = fields.get("data")
    if not isinstance(value, bool):
        raise Refused(f"data must be true or false, got {value!r}")
    return value


class Talkback(ServerListener):
    """The listener's common part: the run's parameters and the client's channels, checked and decoded; the
    subclass applies (:class:`EngineTalkback`, :class:`GraphTalkback`)."""

    def __init__(self, scenario: Scenario | None) -> None:
        self.values: dict[str, float | int | bool] = {}
        self._gains: dict[str, _Gain] = {}
        self._ranges: dict[str, tuple[float | None, float | None]] = {}  # the ROS descriptors' ranges
        self.servos = [] if scenario is None else list(scenario.servos)
        for k, config in enumerate(self.servos):
            gains = config.law_config()
            for spec in flat_specs(law_config_class(config.law)):
                if spec.kind in (float, int, bool) and not spec.info.read_only and "." not in spec.name:
                    name = f"servo_{config.axis_name}.gains.{spec.name}"
                    self._gains[name] = _Gain(k, spec.name)
                    self.values[name] = getattr(gains, spec.name)
                    self._ranges[name] = (spec.info.low, spec.info.high)
        self.compensator = None if scenario is None else scenario.compensator
        if self.compensator is not None and self.compensator.method == "neural":
            self.values[LEARNING_RATE] = float(self.compensator.params["eta"])
            eta = next(spec for spec in flat_specs(compensator_config_class("neural")) if spec.name == "eta")
            self._ranges[LEARNING_RATE] = (eta.info.low, eta.info.high)
        self._override_source, self.max_ratio = "topic", math.inf  # a graph started by hand: its own checks
        if scenario is not None:
            override = scenario.override_config
            self._override_source = ("force_regulator" if scenario.pipeline().has("force_regulator")
                                     else "schedule" if override.has_schedule
                                     else "topic" if scenario.feed_override is not None else "none")
            self.max_ratio = override.max_ratio
        self.requested_ratio, self.held = 1.0, False
        self.server: LiveServer | None = None
        self._channels: dict[tuple[int, int], tuple[str, str]] = {}

    def server_options(self) -> dict[str, Any]:
        """The :class:`LiveServer` keywords: this listener, the capabilities and the encodings a client may send."""
        return {"listener": self, "capabilities": [Capability.Parameters, Capability.ClientPublish],
                "supported_encodings": ["json", "cdr"]}

    def attach(self, server: LiveServer) -> None:
        """The server started with :meth:`server_options` (statuses before it are dropped)."""
        self.server = server

    # Parameters ------------------------------------------------------------------------------------------------

    def on_get_parameters(self, client: Client, param_names: list[str],
                          request_id: str | None = None) -> list[Parameter]:
        """The values asked for (all when none is named); unknown names are left out."""
        names = param_names or list(self.values)
        return [Parameter(name, value=self.values[name]) for name in names if name in self.values]

    def on_set_parameters(self, client: Client, parameters: list[Parameter],
                          request_id: str | None = None) -> list[Parameter]:
        """Each change checked as the node's on-set callback checks it; a refused one keeps its value and is said
        as a warning status with the node's reason. The answer is every parameter's value after the request."""
        for parameter in parameters:
            try:
                self._set(parameter.name, parameter.get_value())
            except CncError as err:
                self._status(f"parameter {parameter.name} refused: {err}", StatusLevel.Warning)
        values = self.on_get_parameters(client, [])
        if self.server is not None:
            self.server.server.publish_parameter_values(values)
        return values

    def _set(self, name: str, value: Any) -> None:
        if name not in self.values:
            raise Refused(f"no such parameter; the run has {sorted(self.values)}")
        old = self.values[name]
        if isinstance(value, bool) != isinstance(old, bool) or not isinstance(value, (int, float)):
            raise Refused(f"{name} must be a {type(old).__name__}, got {value!r}")
        value = float(value) if isinstance(old, float) else value
        self._apply_parameter(name, value)
        self.values[name] = value

    def _apply_parameter(self, name: str, value: float | int | bool) -> None:
        """Apply an accepted parameter's new value, or raise :class:`Refused` (the subclass)."""
        raise NotImplementedError

    # Client publish --------------------------------------------------------------------------------------------

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        """A client's channel: one of :data:`CLIENT_TOPICS`, else a warning status naming them."""
        if channel.topic not in CLIENT_TOPICS:
            self._status(f"client publish on {channel.topic} refused: the run takes {sorted(CLIENT_TOPICS)}",
                         StatusLevel.Warning)
            return
        self._channels[(client.id, channel.id)] = (channel.topic, channel.encoding)

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        """A client's message: decoded, checked and applied; a refusal is a warning status."""
        topic, encoding = self._channels.get((client.id, client_channel_id), ("", ""))
        if not topic:
            return  # refused when it was advertised
        try:
            fields = decode(encoding, CLIENT_TOPICS[topic], data)
            if topic == "/cnc/feed_override":
                self._override(fields)
            elif topic == "/cnc/feed_hold":
                self._check_override_source()
                self.held = flag(fields)
                self._request_ratio(0.0 if self.held else self.requested_ratio)
            else:
                (self._estop if topic == "/cnc/estop" else self._enable)(flag(fields))
        except CncError as err:
            self._status(f"{topic} refused: {err}", StatusLevel.Warning)

    def _override(self, fields: dict[str, Any]) -> None:
        self._check_override_source()
        ratio = message_ratio(number(fields, "requested_ratio"), number(fields, "applied_ratio", 0.0),
                              number(fields, "quantum", 0.0))
        inbox = OverrideInbox(False, self.max_ratio)  # the interpolator's own check
        inbox.latest = self.requested_ratio
        reason = inbox.add(0, ratio)
        if reason is not None:
            raise Refused(reason)
        self.requested_ratio = ratio
        self._request_ratio(0.0 if self.held else ratio)

    def _check_override_source(self) -> None:
        if self._override_source != "topic":
            raise Refused({"none": "this run has no on-line feed override (give the scenario a feed_override "
                                   "section)",
                           "schedule": "this run's override follows its feed_override.schedule",
                           "force_regulator": "this run's override is its force regulator's"}[self._override_source])

    def _request_ratio(self, ratio: float) -> None:
        """Ask the interpolator for ``ratio`` (the subclass)."""
        raise NotImplementedError

    def _estop(self, value: bool) -> None:
        """The e-stop set (true) or released (the subclass)."""
        raise NotImplementedError

    def _enable(self, value: bool) -> None:
        """The axes enabled or disabled (the subclass)."""
        raise NotImplementedError

    def _status(self, text: str, level: StatusLevel) -> None:
        if self.server is not None:
            self.server.server.publish_status(text, level)


class EngineTalkback(Talkback):
    """Listener of the live server of an engine run: what it accepts is applied at the next tick (module
    docstring)."""

    def __init__(self, scenario: Scenario) -> None:
        super().__init__(scenario)
        self.pending: deque[Action] = deque()

    def apply(self, board: Board, stages: list[EngineStage]) -> None:
        """Apply what was accepted since the last tick (the engine's thread, after the tick's stages)."""
        while self.pending:
            self.pending.popleft()(board, stages)

    def _apply_parameter(self, name: str, value: float | int | bool) -> None:
        low, high = self._ranges[name]
        reason = None if isinstance(value, bool) else range_refusal(name.partition(".")[2], low, high, value)
        if reason is not None:
            raise Refused(reason)
        if name == LEARNING_RATE:
            self._set_learning_rate(float(value))
        else:
            self._set_gain(self._gains[name], value)

    def _set_gain(self, gain: _Gain, value: float | int | bool) -> None:
        """Build the servo config the servo node's on-set callback builds (its error is the refusal)."""
        old = self.servos[gain.axis]
        mapping = {**config_values(old), "law_params": {**old.law_params, gain.field: value}}
        config = ServoConfig.from_mapping(mapping, context=f"servo[{old.axis_name}]")
        self.servos[gain.axis] = config

        def retune(board: Board, stages: list[EngineStage]) -> None:
            next(s for s in stages if isinstance(s, ServoStage)).servos[gain.axis].retune(config)
        self.pending.append(retune)

    def _set_learning_rate(self, eta: float) -> None:
        """Build the compensator settings the compensator node builds (its error is the refusal)."""
        assert self.compensator is not None  # the parameter exists only with a neural compensator
        mapping = {**config_values(self.compensator), "params": {**self.compensator.params, "eta": eta}}
        self.compensator = settings = CompensatorSettings.from_mapping(mapping, context="compensator")

        def relearn(board: Board, stages: list[EngineStage]) -> None:
            stage = next(s for s in stages if isinstance(s, CompensatorStage))
            stage.settings, compensator = settings, stage.compensator
            compensator.config = replace(compensator.config, eta=eta)  # type: ignore[attr-defined]  # NeuralCompensator's
        self.pending.append(relearn)

    def _request_ratio(self, ratio: float) -> None:
        def request(board: Board, stages: list[EngineStage]) -> None:
            board.feed_override_request = ratio
        self.pending.append(request)

    def _estop(self, value: bool) -> None:
        if not value:
            return  # nothing latched to release: an e-stop ends an engine run

        def stop(board: Board, stages: list[EngineStage]) -> None:
            raise FaultError(f"e-stop from the live viewer (/cnc/estop true) at t = {board.stamp_ns * 1e-9:.6f} s: "
                             "the machine stopped")
        self.pending.append(stop)

    def _enable(self, value: bool) -> None:
        if not value:
            raise Refused("an engine run has no axis enable (the graph's ~/enable): data false refused; "
                          "/cnc/feed_hold holds the feed, /cnc/estop stops the run")


class GraphBus(Protocol):
    """What :class:`GraphTalkback` asks of the graph (``live/ros.py`` ``RosBus``, on the ``live`` node)."""

    def set_parameter(self, node: str, name: str, value: float | int | bool) -> str | None:
        """Set ``name`` on the namespace's ``node``; the node's reason if it refused, else None."""

    def publish_override(self, ratio: float) -> None:
        """A ``FeedOverride`` with ``ratio`` on the namespace's ``feed_override``."""

    def publish_estop(self, value: bool) -> None:
        """``value`` on the namespace's ``estop``."""

    def enable(self, value: bool) -> list[str]:
        """``~/enable`` on every node that offers it; the refusals (node: reason)."""


class GraphTalkback(Talkback):
    """Listener of the live server of a graph run: parameters through the nodes' parameter services (the node
    refuses, with its reason), client publish onto the suite's topics (``bus``, set once the ``live`` node runs).

    A published message is handed to a thread of its own, which waits for the graph (discovery, acknowledgements)
    and says a refusal as a status: the server's thread only checks and queues."""

    def __init__(self, scenario: Scenario | None) -> None:
        super().__init__(scenario)
        self.bus: GraphBus | None = None
        self._jobs: queue.SimpleQueue[tuple[str, Callable[[GraphBus], Any]] | None] = queue.SimpleQueue()
        self._worker: threading.Thread | None = None

    def _graph(self) -> GraphBus:
        if self.bus is None:
            raise Refused("the live node has not joined the graph yet")
        return self.bus

    def _apply_parameter(self, name: str, value: float | int | bool) -> None:
        node, _, parameter = name.partition(".")
        reason = self._graph().set_parameter(node, parameter, value)
        if reason is not None:
            raise Refused(reason)

    def _later(self, topic: str, job: Callable[[GraphBus], Any]) -> None:
        """Run ``job`` on the bus in the worker thread (started on first use); its error is a status."""
        self._graph()
        if self._worker is None:
            self._worker = threading.Thread(target=self._work, name="live-talkback", daemon=True)
            self._worker.start()
        self._jobs.put((topic, job))

    def _work(self) -> None:
        while (item := self._jobs.get()) is not None:
            topic, job = item
            try:
                refusals = job(self._graph())
                if refusals:
                    raise Refused("; ".join(refusals))
            except CncError as err:
                self._status(f"{topic} refused: {err}", StatusLevel.Warning)

    def close(self) -> None:
        """Stop the worker thread after the requests queued."""
        if self._worker is not None:
            self._jobs.put(None)
            self._worker.join()

    def _request_ratio(self, ratio: float) -> None:
        self._later("/cnc/feed_override", lambda bus: bus.publish_override(ratio))

    def _estop(self, value: bool) -> None:
        self._later("/cnc/estop", lambda bus: bus.publish_estop(value))

    def _enable(self, value: bool) -> None:
        self._later("/cnc/enable", lambda bus: bus.enable(value))


class TalkingEngineLive(EngineLive):
    """:class:`EngineLive` that first applies what the viewer asked for since the last tick."""

    def __init__(self, scenario: Scenario, feed: LiveFeed, rate: float = 1.0, *,
                 talkback: EngineTalkback) -> None:
        super().__init__(scenario, feed, rate)
        self.talkback = talkback

    def __call__(self, board: Board, stages: list[EngineStage]) -> None:
        """Tick ``board.tick``: the viewer's requests, then :meth:`EngineLive.__call__`."""
        if self.talkback.pending:
            self.talkback.apply(board, stages)
        super().__call__(board, stages)
