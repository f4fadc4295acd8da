"""MCAP storage for ``rosbags.rosbag2.Writer``: chunk CRCs and small chunks, a cheap per-message step.

rosbags' own MCAP storage writes every chunk with CRC 0 (a flipped byte goes
unnoticed) and closes a chunk only past 1 MiB (a killed writer loses all of
it). This storage writes the file :class:`cnc_tools.bagio.mcap_writer.McapWriter`
writes, byte-identical to ``mcap.writer.Writer`` (the old path, kept as
:class:`LibraryMcapStorage` for the ``bag-write`` bench) with its
``enable_crcs`` (the CRC of each chunk's records, which both ``rosbags``' reader
and the salvage scan check, and of the summary), ``enable_data_crcs`` (one CRC of
the whole data section, message indexes included, checked by
:func:`cnc_tools.bagio.mcap_salvage.crc_problem`) and a ``chunk_size`` of :data:`CHUNK_SIZE_BYTES`;
chunks stay uncompressed so the salvage scan can enter them. The rosbag2
metadata record carries ``ros_distro: jazzy`` as rosbag2 writes it.
"""
from __future__ import annotations

from io import StringIO
from pathlib import Path
from typing import BinaryIO, Protocol, cast

from mcap.writer import CompressionType
from mcap.writer import Writer as McapFileWriter
from rosbags.interfaces import Connection, ConnectionExtRosbag2, MessageDefinitionFormat
from rosbags.rosbag2.enums import CompressionMode
from ruamel.yaml import YAML

from cnc_contour_control.core.errors import BagError
from cnc_tools.bagio.mcap_writer import McapWriter

#: Smallest chunk before it is closed [bytes]: about 5 ticks of a 2-axis run, so one damaged chunk loses
#: <= 1 % of a short run (105 chunks in the 6.47 s, T = 10 ms paper000_circle_high run).
CHUNK_SIZE_BYTES = 3584
#: Past that, a chunk closes at this share of the bytes before it (:class:`McapWriter`'s ``max_share``): one
#: damaged chunk is <= 0.5 % of a run of any length, and a 60 s 1 kHz run is read in hundreds of chunks, not
#: ten thousand (each chunk costs the reader a fixed step).
CHUNK_SHARE = 1.0 / 200.0
#: The ``library`` field of the MCAP header.
LIBRARY = "cnc_tools (mcap)"
#: The ROS distribution the suite records for (``ros_distro`` of ``metadata.yaml``).
ROS_DISTRO = "jazzy"


def with_ros_distro(metadata_text: str) -> str:
    """The serialized rosbag2 metadata (YAML) with ``ros_distro`` set to :data:`ROS_DISTRO`."""
    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    data = yaml.load(metadata_text)
    info = data.get("rosbag2_bagfile_information", data)
    info["ros_distro"] = ROS_DISTRO
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


class _FileWriter(Protocol):
    """What the storage calls on an MCAP writer (ours or the ``mcap`` library's)."""

    def start(self, profile: str, library: str) -> None: ...
    def register_schema(self, name: str, encoding: str, data: bytes) -> int: ...
    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str]) -> int: ...
    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int) -> None: ...
    def add_metadata(self, name: str, data: dict[str, str]) -> None: ...
    def flush(self) -> None: ...
    def finish(self) -> None: ...


def _our_writer(stream: BinaryIO) -> _FileWriter:
    """:class:`McapWriter` in chunks of :data:`CHUNK_SIZE_BYTES`, growing to :data:`CHUNK_SHARE` of the file."""
    return McapWriter(stream, CHUNK_SIZE_BYTES, max_share=CHUNK_SHARE)


def _library_writer(stream: BinaryIO) -> _FileWriter:
    """``mcap.writer.Writer`` with the same options (uncompressed chunks, chunk and data CRCs)."""
    return McapFileWriter(stream, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.NONE,
                          enable_crcs=True, enable_data_crcs=True)


class CheckedMcapStorage:
    """A rosbags storage writer (``StorageWriter`` protocol) on :class:`McapWriter` with chunk CRCs.

    Besides the protocol, :meth:`channel_id` and :meth:`write_channel` let
    ``BagWriter`` append a message without rosbags' per-message bookkeeping.
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        if compression != CompressionMode.NONE:
            raise BagError(f"bag {path}: compression must be none (the salvage scan reads raw chunks), "
                             f"got {compression.name.lower()}")
        self.path = path / f"{path.name}.mcap"
        self._file = self.path.open("xb")
        self._mcap = self._make_writer(self._file)
        self._mcap.start(profile="ros2", library=LIBRARY)
        self._schemas: dict[str, int] = {}
        self._channels: dict[int, int] = {}
        self.write_channel = self._mcap.add_message
        """Append one message: ``write_channel(channel_id, log_time_ns, data, publish_time_ns)``."""

    _make_writer = staticmethod(_our_writer)

    def add_msgtype(self, connection: Connection) -> None:
        """Register the schema of ``connection``'s message type."""
        encoding = "ros2msg" if connection.msgdef.format == MessageDefinitionFormat.MSG else "ros2idl"
        self._schemas[connection.msgtype] = self._mcap.register_schema(
            connection.msgtype, encoding, connection.msgdef.data.encode())

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Register a channel with its offered QoS profiles (serialized YAML)."""
        ext = cast(ConnectionExtRosbag2, connection.ext)
        self._channels[connection.id] = self._mcap.register_channel(
            connection.topic, ext.serialization_format, self._schemas[connection.msgtype],
            {"offered_qos_profiles": offered_qos_profiles})

    def channel_id(self, connection: Connection) -> int:
        """The MCAP channel id of a registered connection."""
        return self._channels[connection.id]

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Append one message; log and publish time are ``timestamp`` [ns]."""
        self._mcap.add_message(self._channels[connection.id], timestamp, bytes(data), timestamp)

    def flush(self) -> None:
        """Close the chunk in progress and hand everything written to the OS."""
        self._mcap.flush()

    def close(self, version: int, metadata: str) -> None:
        """Write the rosbag2 metadata record, the summary and the footer."""
        _ = version
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": with_ros_distro(metadata).strip()})
        self._mcap.finish()
        self._file.close()

    def abort(self) -> None:
        """Close without summary."""
        self._file.close()


class LibraryMcapStorage(CheckedMcapStorage):
    """The same storage on ``mcap.writer.Writer`` (the path before :class:`McapWriter`; bench and tests)."""

    _make_writer = staticmethod(_library_writer)
