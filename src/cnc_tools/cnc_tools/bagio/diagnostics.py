"""The ``/diagnostics`` statuses recorded in a bag, as ROS-free :class:`~cnc_tools.analysis.verdict.Status` (no rclpy).

A run's nodes report faults and the run's end (``run finished`` with its tick
count) on ``/diagnostics``; since runs are isolated the runner remaps it into
the run's namespace (``/cnc/<run id>/diagnostics``). Both spellings are read.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from cnc_contour_control.core import topics as t
from cnc_contour_control.core.errors import BagError
from cnc_tools.analysis.verdict import Status
from cnc_tools.bagio.raw_bag import locate, read_raw
from cnc_tools.bagio.recording import in_some_namespace
from cnc_tools.bagio.typestore import project_typestore

_RELATIVE = t.DIAGNOSTICS.name.lstrip("/")


def read_statuses(bag: str | Path) -> tuple[str, tuple[Status, ...]]:
    """The run's namespace (where its diagnostics topic lives; ``/cnc`` for ``/diagnostics``) and every status.

    Raises
    ------
    BagError
        The bag cannot be read, or a recorded status cannot be decoded.
    """
    raw, _ = read_raw(locate(Path(bag)), lambda topic: in_some_namespace(topic, (_RELATIVE,)))
    store = raw.typestore or project_typestore()
    statuses: list[Status] = []
    namespace = t.DEFAULT_NAMESPACE
    for topic, msgtype in sorted(raw.msgtypes.items()):
        if msgtype != t.DIAGNOSTICS.type_name:
            continue
        if topic != t.DIAGNOSTICS.name:
            namespace = topic[: -len(_RELATIVE) - 1]
        for index, data in enumerate(raw.data[topic]):
            try:
                message: Any = store.deserialize_cdr(data, msgtype)
            except Exception as err:
                raise BagError(f"{bag}: {topic} message {index} cannot be decoded "
                               f"({type(err).__name__}: {err})") from err
            statuses += [Status(int(s.level), str(s.name), str(s.message), {kv.key: kv.value for kv in s.values})
                         for s in message.status]
    return namespace, tuple(statuses)
