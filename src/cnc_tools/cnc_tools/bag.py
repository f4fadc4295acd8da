"""Bag I/O: write MCAP bags in the rosbag2 layout, read a recorded run back as arrays.

A bag is a folder ``<name>/`` holding ``metadata.yaml`` (rosbag2 version 9 with
the per-topic message counts) and ``<name>.mcap`` (ros2 profile, ``ros2msg``
schemas, CDR messages in chunks, message indexes and a summary), written by
``rosbags.rosbag2.Writer``; ``ros2 bag``, Foxglove, ``rosbags`` and ``mcap`` read it.

Reading goes through ``rosbags``' ``AnyReader`` (the file's index). When that
fails (a truncated or damaged file) the reader scans the file record by record
and keeps every intact message of the readable prefix. ``BagIntegrity`` says how
the file was read and how many messages were lost, or that the loss is unknown.
A damaged file is never reported complete. No rclpy: the recorder hands over raw
CDR bytes.
"""
from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from rosbags.highlevel import AnyReader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from ruamel.yaml import YAML

from cnc_contour_control.errors import BagError
from cnc_tools.run import BagIntegrity, RecordedRun, TopicNames, build_run
from cnc_tools.typestore import project_typestore

PATH_TYPE = "cnc_contour_interfaces/msg/Path"
_NO_TIME = QosTime(sec=0, nsec=0)
#: QoS offered for latched topics (``/cnc/path``), so ``ros2 bag play`` republishes them transient-local.
TRANSIENT_LOCAL_QOS = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL,
                          _NO_TIME, _NO_TIME, QosLiveliness.AUTOMATIC, _NO_TIME, False)
