"""Raw reading of a bag: locate its MCAP file, read the CDR bytes of wanted topics with their log times.

Reading goes through ``rosbags``' ``AnyReader`` (the file's index); the messages
themselves are located with numpy (:mod:`cnc_tools.bagio.mcap_index`) when that
module vouches for the file, which gives rosbags' messages in rosbags' order. When that
fails (a truncated or damaged file) the salvage scan (:mod:`cnc_tools.bagio.mcap_salvage`)
keeps every intact message of the readable prefix. Either way the result says,
in a :class:`~cnc_tools.run_record.BagIntegrity`, how the file was read and
how many messages were lost. Shared by ``read_bag`` (scoring) and replay. No rclpy.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys.store import Typestore

from cnc_contour_control.core.errors import BagError
from cnc_tools.bagio.mcap_index import MessageLocations, locate_messages
from cnc_tools.bagio.mcap_salvage import crc_problem, scan_mcap, scan_typestore
from cnc_tools.bagio.typestore import project_typestore
from cnc_tools.run_record import BagIntegrity

TopicFilter = Callable[[str], bool]


@dataclass(frozen=True)
class BagSource:
    """The MCAP file of a bag and what its ``metadata.yaml`` says (counts ``None`` when unusable)."""

    mcap_path: Path
    metadata_counts: Mapping[str, int] | None
    problems: tuple[str, ...]


@dataclass
class RawBag:
    """Raw CDR messages of the wanted topics, per topic in the order read.

    ``log_time_ns[topic][i]`` is the log time of ``data[topic][i]``; ``order`` the
    topic of every message in the order the file was read (log time, then file
    order), so the messages of several topics can be merged back into that order.
    """

    msgtypes: dict[str, str] = field(default_factory=dict)
    data: dict[str, list[bytes | memoryview]] = field(default_factory=dict)
    log_time_ns: dict[str, list[int]] = field(default_factory=dict)
    order: list[str] = field(default_factory=list)
    typestore: Typestore | None = None

    def declare(self, topic: str, msgtype: str) -> None:
        """A topic of the bag; its messages, if some were appended already, are kept."""
        self.msgtypes[topic] = msgtype
        self.data.setdefault(topic, [])
        self.log_time_ns.setdefault(topic, [])

    def append(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """One message of a declared topic, after those read before it."""
        self.data[topic].append(data)
        self.log_time_ns[topic].append(log_time_ns)
        self.order.append(topic)

    def in_read_order(self) -> Iterator[tuple[str, int, bytes | memoryview]]:
        """(topic, log time ns, data) of every message, in the order read."""
        position = dict.fromkeys(self.data, 0)
        for topic in self.order:
            i = position[topic]
            position[topic] = i + 1
            yield topic, self.log_time_ns[topic][i], self.data[topic][i]


# =========================================================================== locating and metadata
#: libyaml's safe loader where PyYAML has it (a tenth of the pure-Python parsers' time on a run's metadata.yaml).
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _metadata_counts(folder: Path) -> tuple[dict[str, int] | None, list[str], tuple[str, ...]]:
    """Per-topic counts and file names from ``metadata.yaml``; ``None`` and a note when unusable."""
    meta_path = folder / "metadata.yaml"
    if not meta_path.is_file():
        return None, [], (f"{meta_path} is missing",)
    try:
        info = yaml.load(meta_path.read_text(encoding="utf-8"), _SAFE_LOADER)["rosbag2_bagfile_information"]
        counts = {str(t["topic_metadata"]["name"]): int(t["message_count"]) for t in info["topics_with_message_count"]}
        return counts, [Path(str(p)).name for p in info.get("relative_file_paths", [])], ()
    except Exception as err:
        return None, [], (f"{meta_path} is unreadable ({type(err).__name__}: {err})",)


def locate(path: Path) -> BagSource:
    """The MCAP file of a bag folder (or the file itself) and its metadata.

    Raises
    ------
    BagError
        The path does not exist, holds no ``.mcap`` file, or a split bag.
    """
    if not path.exists():
        raise BagError(f"bag {path} does not exist")
    folder = path if path.is_dir() else path.parent
    counts, listed, problems = _metadata_counts(folder)
    if path.is_file():
        return BagSource(path, counts if path.name in listed else None, problems)
    names = [n for n in listed if (folder / n).is_file()] or sorted(p.name for p in folder.glob("*.mcap"))
    if not names:
        raise BagError(f"bag {path} holds no .mcap file")
    if len(names) > 1:
        raise BagError(f"bag {path} is split into {names}; split bags are not supported")
    return BagSource(folder / names[0], counts, problems)


# =========================================================================== the two ways of reading
def _take_located(raw: RawBag, data: bytes, found: MessageLocations) -> None:
    """Hand the located messages to ``raw``, topic by topic and in read order, without a step per message."""
    names = [found.topics.get(cid, "") for cid in range(max(found.topics, default=-1) + 1)]
    raw.order = [names[cid] for cid in found.channel.tolist()]
    for cid, topic in found.topics.items():
        mine = found.channel == cid
        raw.data[topic] = [data[a:b] for a, b in zip(found.start[mine].tolist(), found.end[mine].tolist(), strict=True)]
        raw.log_time_ns[topic] = found.log_time_ns[mine].tolist()


def _read_indexed(source: BagSource, wanted: TopicFilter, data: bytes) -> tuple[RawBag, dict[str, int]]:
    """Read through rosbags (the MCAP index). Returns the messages and the summary's counts.

    rosbags gives the topics, types and typestore; the messages come from
    :func:`~cnc_tools.bagio.mcap_index.locate_messages` (the same messages in the
    same order, found with numpy) when it vouches for the file, else from rosbags.
    """
    target = source.mcap_path.parent if source.metadata_counts is not None else source.mcap_path
    raw = RawBag()
    with AnyReader([target], default_typestore=project_typestore()) as reader:
        connections = [c for c in reader.connections if wanted(c.topic)]
        for conn in connections:
            raw.declare(conn.topic, conn.msgtype)
        found = locate_messages(data, raw.msgtypes) if connections else None
        if found is not None:
            _take_located(raw, data, found)
        else:
            for conn, log_time_ns, message in reader.messages(connections=connections) if connections else ():
                raw.append(conn.topic, log_time_ns, message)
        raw.typestore = reader.typestore
    return raw, {c.topic: c.msgcount for c in connections}


def _read_scanned(source: BagSource, wanted: TopicFilter, index_error: str) -> tuple[RawBag, BagIntegrity]:
    raw = RawBag()

    def sink(topic: str, log_time_ns: int, data: bytes) -> None:
        if topic not in raw.data:
            raw.declare(topic, "")  # its type is known once the scan is over
        raw.append(topic, log_time_ns, data)

    scan, problem = scan_mcap(source.mcap_path, wanted, sink)
    for topic, msgtype in scan.topic_types().items():
        raw.declare(topic, msgtype)
    raw.typestore = scan_typestore(scan)
    expected, expected_source = source.metadata_counts, "metadata.yaml"
    if expected is None and scan.statistics_counts() is not None:
        expected, expected_source = scan.statistics_counts(), "mcap summary"
    problems = (f"index unreadable ({index_error})", *scan.damage, *((problem,) if problem else ()), *source.problems)
    found = {topic: scan.counts.get(topic, 0) for topic in raw.msgtypes}
    found.update({t: scan.counts.get(t, 0) for t in (expected or {}) if wanted(t)})
    integrity = BagIntegrity(False, "scan", found, expected, expected_source if expected else "unknown", problems)
    return raw, integrity


def read_raw(source: BagSource, wanted: TopicFilter) -> tuple[RawBag, BagIntegrity]:
    """Read the wanted topics through the index, else by the salvage scan; say how intact the bag is.

    A file whose CRCs do not match is never read through its index: the scan
    keeps what its chunk CRCs vouch for, and the bag is not complete.
    """
    try:
        data = source.mcap_path.read_bytes()
    except OSError as err:
        raise BagError(f"cannot read {source.mcap_path}: {err}") from err
    crc = crc_problem(data)
    if crc:
        return _read_scanned(source, wanted, crc)
    try:
        raw, summary_counts = _read_indexed(source, wanted, data)
    except Exception as err:
        return _read_scanned(source, wanted, f"{type(err).__name__}: {err}")
    expected = source.metadata_counts if source.metadata_counts is not None else summary_counts
    found = {topic: len(data) for topic, data in raw.data.items()}
    found.update({t: found.get(t, 0) for t in expected if wanted(t)})
    mismatch = tuple(f"{t}: {found[t]} of {expected.get(t, 0)} messages"
                     for t in found if found[t] != expected.get(t, 0))
    source_name = "metadata.yaml" if source.metadata_counts is not None else "mcap summary"
    return raw, BagIntegrity(not mismatch, "index", found, expected, source_name, mismatch + source.problems)
