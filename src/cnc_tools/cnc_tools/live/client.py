"""A protocol-level client of the live server (the Foxglove WebSocket protocol, ``foxglove.sdk.v1``), no browser.

For tests and ``cnc-contour bench live``: connect, read the advertised channels, subscribe by topic, and collect
messages (topic, log time, arrival time, payload) until a condition holds, the server closes, or a timeout.
``websockets`` (pinned in requirements/python.txt) is imported only here.
"""
from __future__ import annotations

import json
import struct
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from cnc_contour_control.core.errors import CncError

SUBPROTOCOL = "foxglove.sdk.v1"
#: Server -> client binary opcode of a message on a subscription: u8 op, u32 subscription, u64 log time.
MESSAGE_DATA = 0x01
_HEADER = struct.Struct("<BIQ")
#: Server -> client playback state: u8 op, u8 status, u64 time [ns], f32 speed, u8 did_seek, u32 id length, id.
PLAYBACK_STATE = 0x05
_STATE = struct.Struct("<BBQfBI")
#: Client -> server playback control request: u8 op, u8 command (0 play, 1 pause), f32 speed, u8 seek given,
#: u64 seek time [ns], u32 id length, id.
PLAYBACK_CONTROL = 0x03
_CONTROL = struct.Struct("<BBfBQI")
#: Client -> server message on a client channel: u8 op, u32 channel id, payload.
CLIENT_MESSAGE = 0x01
_CLIENT_HEADER = struct.Struct("<BI")
#: Playback statuses by their code on the wire.
PLAYBACK_STATUSES = ("playing", "paused", "buffering", "ended")


@dataclass(frozen=True)
class Received:
    """One message as the client got it: topic, log time [ns], arrival wall time [ns], payload."""

    topic: str
    log_time_ns: int
    arrived_ns: int
    payload: bytes

    def json(self) -> Any:
        """The payload of a JSON channel."""
        return json.loads(self.payload)


@dataclass(frozen=True)
class Playback:
    """A playback state from the server: status (``PLAYBACK_STATUSES``), timeline time [ns], speed, whether a seek
    caused it, and the id of the request it answers ("" for none)."""

    status: str
    time_ns: int
    speed: float
    did_seek: bool
    request_id: str


class LiveClient:
    """A synchronous client: ``with LiveClient(url) as client: client.subscribe([...]); client.collect(...)``."""

    def __init__(self, url: str, timeout_s: float = 30.0) -> None:
        from websockets.sync.client import connect

        protocols = [SUBPROTOCOL]
        self.socket = connect(url, subprotocols=protocols,  # type: ignore[arg-type]  # a NewType of str there
                              open_timeout=timeout_s, max_size=None).__enter__()  # closed by close()
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}
        self._by_subscription: dict[int, str] = {}
        self.closed = False
        self.pending: list[Received] = []
        self.playback: list[Playback] = []
        self.statuses: list[dict[str, Any]] = []
        self.parameters: dict[str, list[dict[str, Any]]] = {}  # parameterValues answers by request id ("": none)
        self._client_channels: dict[str, int] = {}

    def _handle(self, frame: str | bytes, arrived_ns: int) -> None:
        if isinstance(frame, str):
            op = json.loads(frame)
            if op.get("op") == "serverInfo":
                self.server_info = op
            elif op.get("op") == "advertise":
                self.channels.update({c["topic"]: c for c in op["channels"]})
            elif op.get("op") == "status":
                self.statuses.append(op)
            elif op.get("op") == "parameterValues":
                self.parameters[str(op.get("id") or "")] = op["parameters"]
            return
        if frame and frame[0] == PLAYBACK_STATE:
            _, status, time_ns, speed, did_seek, length = _STATE.unpack_from(frame)
            request_id = bytes(frame[_STATE.size:_STATE.size + length]).decode()
            self.playback.append(Playback(PLAYBACK_STATUSES[status], time_ns, speed, bool(did_seek), request_id))
        if frame and frame[0] == MESSAGE_DATA:
            _, subscription, log_time_ns = _HEADER.unpack_from(frame)
            self.pending.append(Received(self._by_subscription.get(subscription, "?"), log_time_ns, arrived_ns,
                                         bytes(frame[_HEADER.size:])))

    def poll(self, timeout_s: float) -> bool:
        """Read frames for up to ``timeout_s``; False once the server closed the connection."""
        from websockets.exceptions import ConnectionClosed

        deadline = time.monotonic() + timeout_s
        try:
            while (left := deadline - time.monotonic()) > 0:
                frame = self.socket.recv(timeout=left)
                self._handle(frame, time.time_ns())
        except TimeoutError:
            return True
        except ConnectionClosed:
            self.closed = True
            return False
        return True

    def wait_channels(self, topics: Iterable[str], timeout_s: float = 30.0) -> dict[str, dict[str, Any]]:
        """The advertised channels of ``topics``, once all are there; an error names those missing."""
        wanted = set(topics)
        deadline = time.monotonic() + timeout_s
        while not wanted <= self.channels.keys() and time.monotonic() < deadline and not self.closed:
            self.poll(0.05)
        missing = sorted(wanted - self.channels.keys())
        if missing:
            raise CncError(f"live server did not advertise {missing} within {timeout_s} s; "
                           f"advertised: {sorted(self.channels)}")
        return {topic: self.channels[topic] for topic in wanted}

    def subscribe(self, topics: Iterable[str]) -> None:
        """Subscribe to these (advertised) topics."""
        subscriptions = []
        for topic in topics:
            subscription = len(self._by_subscription) + 1
            self._by_subscription[subscription] = topic
            subscriptions.append({"id": subscription, "channelId": self.channels[topic]["id"]})
        self.socket.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def control_playback(self, play: bool, speed: float, request_id: str, seek_ns: int | None = None) -> Playback:
        """Ask the server to play or pause at ``speed`` (from ``seek_ns`` when given); its answer to ``request_id``."""
        frame = _CONTROL.pack(PLAYBACK_CONTROL, 0 if play else 1, speed, seek_ns is not None, seek_ns or 0,
                              len(request_id.encode())) + request_id.encode()
        self.socket.send(frame)
        deadline = time.monotonic() + 30.0
        while not self.closed and time.monotonic() < deadline:
            answers = [p for p in self.playback if p.request_id == request_id]
            if answers:
                return answers[-1]
            self.poll(0.02)
        raise CncError(f"the live server did not answer playback request {request_id!r} within 30 s")

    def get_parameters(self, names: Iterable[str], request_id: str) -> dict[str, Any]:
        """The server's parameters ``names`` (all when empty), by name."""
        self.socket.send(json.dumps({"op": "getParameters", "parameterNames": list(names), "id": request_id}))
        return self._parameter_answer(request_id)

    def set_parameters(self, values: dict[str, Any], request_id: str) -> dict[str, Any]:
        """Set parameters; the server's answer: every parameter's value after the request, by name."""
        self.socket.send(json.dumps({"op": "setParameters", "id": request_id,
                                     "parameters": [{"name": k, "value": v} for k, v in values.items()]}))
        return self._parameter_answer(request_id)

    def _parameter_answer(self, request_id: str) -> dict[str, Any]:
        deadline = time.monotonic() + 30.0
        while request_id not in self.parameters and not self.closed and time.monotonic() < deadline:
            self.poll(0.02)
        if request_id not in self.parameters:
            raise CncError(f"the live server did not answer parameter request {request_id!r} within 30 s")
        return {p["name"]: p.get("value") for p in self.parameters[request_id]}

    def advertise(self, topic: str, schema_name: str, encoding: str = "json") -> None:
        """Offer a channel to publish on (client publish)."""
        channel = self._client_channels[topic] = len(self._client_channels) + 1
        self.socket.send(json.dumps({"op": "advertise", "channels": [
            {"id": channel, "topic": topic, "encoding": encoding, "schemaName": schema_name}]}))

    def publish(self, topic: str, payload: bytes | dict[str, Any]) -> None:
        """A message on an advertised channel (a mapping is sent as JSON)."""
        data = json.dumps(payload).encode() if isinstance(payload, dict) else payload
        self.socket.send(_CLIENT_HEADER.pack(CLIENT_MESSAGE, self._client_channels[topic]) + data)

    def collect(self, done: Callable[[list[Received]], bool], timeout_s: float) -> list[Received]:
        """Messages received until ``done(received)`` holds, the server closes, or ``timeout_s`` passes."""
        deadline = time.monotonic() + timeout_s
        while not done(self.pending) and not self.closed and time.monotonic() < deadline:
            self.poll(0.05)
        return self.pending

    def close(self) -> None:
        """Close the connection."""
        self.socket.close()

    def __enter__(self) -> LiveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
