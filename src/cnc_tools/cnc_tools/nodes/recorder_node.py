"""Recorder node: writes a run's topics to MCAP (rosbag2 layout) as raw CDR, losing nothing."""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray

from cnc_contour_control.errors import BagError
from cnc_contour_control.nodes.common import LATCHED_QOS, LOCKSTEP_QOS, SuiteNode, describe, message_class, spin_node, wall_time_s
from cnc_plant_sim.nodes.plant_node import RUN_FINISHED
from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.recording import Completion, header_stamp_ns, per_tick_topics, run_topics



#: Topics stamped in wall time: logged at the simulation time of the latest message recorded before them.
WALL_STAMPED = ("/diagnostics",)


class RecorderNode(SuiteNode):
    """Subscribes raw to every topic of the run and appends each message to the bag."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        output = self.declare("output", "", describe("bag folder to create (must not exist)", read_only=True))
        axes = self.declare("axes", ["x", "y"], describe("axis names (one command topic each)", read_only=True))
        optional = self.declare("optional_topics", [""], describe("further run topics to record", read_only=True))
        self.drain_timeout_s = self.declare("drain_timeout_s", 10.0, describe("wait for late messages after the run ends, s", 0.1, 600.0, True))
        if not output:
            raise BagError("recorder: parameter output (the bag folder) is required")
        topics = run_topics(self.get_namespace(), axes, [t for t in optional if t])
        self.writer = BagWriter(output, topics)
        self.completion = Completion(per_tick_topics(topics, self.get_namespace()))
        self.ended_at_s: float | None = None
        self.latest_sim_ns = 0
        for topic, type_name in topics.items():
            qos = LATCHED_QOS if type_name.endswith("/Path") else LOCKSTEP_QOS
            self.create_subscription(message_class(type_name, topic), topic, self._writer_for(topic), qos, raw=True)
        self.create_timer(0.05, self.guarded(self._check_done))

    def _writer_for(self, topic: str) -> Any:
        def write(cdr: bytes) -> None:
            if topic in WALL_STAMPED:
                self.writer.write(topic, self.latest_sim_ns, cdr)
                self._watch_run_end(cdr)
                return
            stamp_ns = header_stamp_ns(cdr)
            self.latest_sim_ns = max(self.latest_sim_ns, stamp_ns)
            self.writer.write(topic, stamp_ns, cdr)

        return self.guarded(write)

    def _watch_run_end(self, cdr: bytes) -> None:
        from rclpy.serialization import deserialize_message

        for status in deserialize_message(cdr, DiagnosticArray).status:
            values = {kv.key: kv.value for kv in status.values}
            if status.message == RUN_FINISHED and "ticks" in values:
                self.completion.ticks = int(values["ticks"])
                self.ended_at_s = wall_time_s()

    def _check_done(self) -> None:
        counts = self.writer.message_counts
        if self.completion.complete(counts):
            self.finished = True
        elif self.ended_at_s is not None and wall_time_s() - self.ended_at_s > self.drain_timeout_s:
            self.fault(f"recorder: run ended but messages are missing after {self.drain_timeout_s} s: "
                       f"{self.completion.missing(counts)}")

    def destroy_node(self) -> None:
        """Close the bag (MCAP summary and metadata.yaml) on every way out."""
        self.writer.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_tools recorder --ros-args -p output:=bags/run1``."""
    raise SystemExit(spin_node(RecorderNode, args))
