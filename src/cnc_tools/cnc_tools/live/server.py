"""The live server: a foxglove-sdk WebSocket server on loopback, with the suite's channels.

One :class:`LiveServer` owns one foxglove ``Context``, so two servers in one process (a test beside a run)
never share a channel. ROS messages go out as they are on the wire: message encoding ``cdr``, schema encoding
``ros2msg`` with the text the recorder writes into the bags (rosbags' ``generate_msgdef`` of the suite's
typestore), so Foxglove decodes them as it decodes our bags. Derived streams are JSON with a JSON schema.

Extension points (later capabilities): ``listener`` (a ``foxglove.websocket.ServerListener``: parameters,
client publish, playback control), ``capabilities``, ``services``, ``supported_encodings`` and
``playback_time_range`` are handed to ``foxglove.start_server`` as given.

Nothing here calls a cloud API or downloads anything: ``start_server`` only binds a local socket.
"""
from __future__ import annotations

import ipaddress
import json
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TextIO

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.bagio.typestore import project_typestore

if TYPE_CHECKING:
    from foxglove import Channel, Schema

#: Default address and port (the Foxglove app's default ``ws://127.0.0.1:8765``).
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: Outgoing messages buffered per client before the oldest data message is dropped.
BACKLOG_MESSAGES = 4096


@dataclass(frozen=True)
class LiveConfig:
    """Where the live server listens.

    Attributes
    ----------
    host : str
        Address bound; anything but loopback is said loudly on stderr at start.
    port : int
        TCP port, 0 for any free one (tests).
    name : str
        Server name the client shows.
    """

    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    name: str = "cnc-contour"

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ConfigError(f"--live-port must be in [0, 65535], got {self.port}")
        if not self.host.strip():
            raise ConfigError(f"--live-host must name an address, got {self.host!r}")

    @property
    def loopback(self) -> bool:
        """True when only this machine can connect."""
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False


def ros_schema(type_name: str) -> Schema:
    """The ``ros2msg`` schema of a suite type, the text the bags hold."""
    from foxglove import Schema

    text = project_typestore().generate_msgdef(type_name, ros_version=2)[0]
    return Schema(name=type_name, encoding="ros2msg", data=text.encode("utf-8"))


class LiveServer:
    """A foxglove-sdk WebSocket server and its channels; close it (or use ``with``) to free the port."""

    def __init__(self, config: LiveConfig, *, listener: Any = None, capabilities: Sequence[Any] = (),
                 services: Sequence[Any] = (), supported_encodings: Sequence[str] = (),
                 playback_time_range: tuple[int, int] | None = None, warn: TextIO | None = None) -> None:
        self.config = config
        if not config.loopback:
            print(f"WARNING: the live server listens on {config.host}:{config.port}, NOT loopback: anyone who "
                  "reaches this address sees the run; give no --live-host to keep it on 127.0.0.1",
                  file=warn or sys.stderr, flush=True)
        import foxglove  # loaded only when a server starts: the CLI stays light without --live

        self.context = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name=config.name, host=config.host, port=config.port, capabilities=list(capabilities) or None,
                server_listener=listener, supported_encodings=list(supported_encodings) or None,
                services=list(services) or None, context=self.context, playback_time_range=playback_time_range,
                message_backlog_size=BACKLOG_MESSAGES)
        except RuntimeError as err:  # foxglove's FoxgloveError: the port taken, the address unknown
            raise ConfigError(f"live server: cannot listen on --live-host {config.host} --live-port {config.port} "
                              f"({err}); choose another port (0: any free one)") from err
        self.channels: dict[str, Any] = {}

    @property
    def port(self) -> int:
        """The port bound (the chosen one when the config asked for 0)."""
        return int(self.server.port)

    @property
    def url(self) -> str:
        """``ws://host:port`` to give the Foxglove app."""
        return f"ws://{self.config.host}:{self.port}"

    def ros_channel(self, topic: str, type_name: str) -> Channel:
        """The channel of a ROS topic (made on first use): CDR with the bag's ``ros2msg`` schema."""
        from foxglove import Channel

        channel = self.channels.get(topic)
        if channel is None:
            channel = Channel(topic, message_encoding="cdr", schema=ros_schema(type_name), context=self.context,
                              metadata={"ros_type": type_name})
            self.channels[topic] = channel
        return channel

    def json_channel(self, topic: str, schema: dict[str, Any]) -> Channel:
        """A JSON channel with its JSON schema, named by the schema's ``title`` (made on first use)."""
        from foxglove import Channel, Schema

        channel = self.channels.get(topic)
        if channel is None:
            typed = Schema(name=str(schema.get("title", topic)), encoding="jsonschema",
                           data=json.dumps(schema).encode("utf-8"))
            channel = Channel(topic, message_encoding="json", schema=typed, context=self.context)
            self.channels[topic] = channel
        return channel

    def typed_channel(self, topic: str, kind: str) -> Any:
        """A channel of a foxglove schema (``Log``, ``SceneUpdate``: ``foxglove.channels.<kind>Channel``)."""
        channel = self.channels.get(topic)
        if channel is None:
            from foxglove import channels

            channel = getattr(channels, f"{kind}Channel")(topic, context=self.context)
            self.channels[topic] = channel
        return channel

    def subscribed(self, topics: Iterable[str]) -> bool:
        """Whether a client's subscription to each of ``topics`` (those with a channel) has reached the server: a
        message sent before then goes to no one."""
        return all(self.channels[topic].has_sinks() for topic in topics if topic in self.channels)

    def close(self) -> None:
        """Stop the server (clients are disconnected, the port is freed)."""
        self.server.stop()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
