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

    def _handle(self, frame: str | bytes, arrived_ns: int) -> None:
        if isinstance(frame, str):
            op = json.loads(frame)
            if op.get("op") == "serverInfo":
                self.server_info = op
            elif op.get("op") == "advertise":
                self.channels.update({c["topic"]: c for c in op["channels"]})
            return
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
