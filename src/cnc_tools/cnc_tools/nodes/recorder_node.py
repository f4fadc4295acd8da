"""Recorder node: writes a run's topics to MCAP (rosbag2 layout) as raw CDR, losing nothing."""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter

from cnc_contour_control.core import topics
from cnc_contour_control.core.errors import BagError
from cnc_contour_control.core.stages import STAGES
from cnc_contour_control.core.topics import DIAGNOSTICS, RUN_FINISHED, RUN_ID_KEY, TICKS_KEY
from cnc_contour_control.nodes.common import (
    LATCHED_QOS,
    LOCKSTEP_QOS,
    SuiteNode,
    describe,
    message_class,
    spin_node,
    wall_time_s,
)
from cnc_tools.bagio.bag import BagWriter
from cnc_tools.bagio.recording import (
    Completion,
    header_stamp_ns,
    is_latched,
    is_wall_stamped,
    per_tick_topics,
    run_topics,
)

#: Wall seconds between flushes of the bag to disk (what a SIGKILLed recorder can lose at most).
FLUSH_PERIOD_S = 1.0
#: Wall seconds the recorder waits for the plant's /diagnostics writer before it reads joint_states anyway.
GATE_WAIT_S = 10.0


class RecorderNode(SuiteNode):
    """Subscribes raw to every topic of the run (its namespace, remaps applied) and appends each message to the bag.

    Statuses (``/diagnostics``, stamped at their node's last tick, which may lag
    the run) are logged at the simulation time of the latest message recorded
    before them. The run's end is the plant's
    "run finished" status from this run (its run id, or its node's namespace).
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("recorder", **kwargs)
        output = self.declare("output", "", describe("bag folder to create (must not exist)", read_only=True))
        axes = self.declare("axes", ["x", "y"], describe("axis names (one command topic each)", read_only=True))
        optional = self.declare("optional_stages", Parameter.Type.STRING_ARRAY, describe(
            "optional stages of the run whose topics are recorded too: "
            f"{sorted(s for s in STAGES if STAGES[s].optional)}",
            read_only=True)) or []
        outputs = self.declare("optional_outputs", Parameter.Type.STRING_ARRAY, describe(
            "optional outputs the run switches on (the plant's tool_position with machine faults), recorded too",
            read_only=True)) or []
        self.drain_timeout_s = self.declare("drain_timeout_s", 10.0,
                                            describe("wait for late messages after the run ends, s", 0.1, 600.0, True))
        if not output:
            raise BagError("recorder: parameter output (the bag folder) is required")
        namespace = self.get_namespace()
        # Resolved names: the runner's remaps (/clock, /diagnostics into the run's namespace) apply.
        recorded = run_topics(namespace, axes, optional, outputs)
        topics = {self.resolve_topic_name(name): ty for name, ty in recorded.items()}
        self.writer = BagWriter(output, topics)
        per_tick = per_tick_topics(namespace, axes, optional, outputs)
        self.completion = Completion(tuple(self.resolve_topic_name(n) for n in per_tick))
        self.ended_at_s: float | None = None
        #: Wall time the run's joint_states writer (the plant) left the graph with no run end heard, if it did.
        self.plant_left_at_s: float | None = None
        self._plant_seen = False
        self.latest_sim_ns = 0
        self.latched_first = latched_first = self.declare("latched_first", False, describe(
            "subscribe the per-tick topics only once the latched ones (the path) are in the bag: for a run whose "
            "plant waits for every reader of joint_states (the runner's graph), not for a replay", read_only=True))
        latched = {topic: ty for topic, ty in topics.items() if is_latched(ty)}
        self._awaited = set(latched) if latched_first else set()
        self._later = {topic: ty for topic, ty in topics.items() if topic not in latched}
        for topic, type_name in latched.items():
            self._subscribe(topic, type_name, LATCHED_QOS)
        if not self._awaited:
            self._subscribe_per_tick()
        else:
            self.get_logger().info(f"waiting for the latched {sorted(latched)} before reading the run's topics")
        self.create_timer(0.05, self.guarded(self._check_done))
        self.create_timer(FLUSH_PERIOD_S, self.guarded(self.writer.flush))  # a killed recorder loses <= 1 s

    def run_stamp_ns(self) -> int:
        """The run's time for a status: the latest simulation stamp recorded (0 before any)."""
        return int(getattr(self, "latest_sim_ns", 0))  # set once the bag is open: a refusal before reports 0

    def _subscribe(self, topic: str, type_name: str, qos: Any) -> None:
        self.create_subscription(message_class(type_name, topic), topic, self._writer_for(topic, type_name), qos,
                                 raw=True)

    def _subscribe_per_tick(self) -> None:
        """The run's other topics, subscribed only once the latched ones (the path) are in the bag.

        The plant starts ticking only when every reader of ``joint_states``
        has matched, so a run cannot begin, or die, before the recorder holds
        the program's geometry: a bag of a run killed at its first tick can
        still be scored. ``joint_states`` comes last, once this node has seen
        the plant's ``/diagnostics`` writer (:meth:`_subscribe_joint_states`).
        """
        gate = self.resolve_topic_name(topics.JOINT_STATES.name) if self.latched_first else ""
        for topic, type_name in self._later.items():
            if topic != gate:
                self._subscribe(topic, type_name, LOCKSTEP_QOS)
        self._gate_topic = (gate, self._later[gate]) if gate in self._later else None
        self._later = {}
        if self._gate_topic is not None:
            self._gate_since_s = wall_time_s()
            self._gate_timer = self.create_timer(0.02, self.guarded(self._subscribe_joint_states))

    def _subscribe_joint_states(self) -> None:
        """Subscribe ``joint_states``, the topic the plant's start waits on, once the run's end can be heard.

        The plant's "run finished" comes on ``/diagnostics``, which is not
        gated: had the plant matched this node's ``joint_states`` reader
        before its ``/diagnostics`` reader, a short run could end, its report
        unheard, and the recorder wait forever. Endpoints are announced in the
        order they are made, so the plant matches the ``/diagnostics`` reader
        first; this node waits until it has itself discovered a ``/diagnostics``
        writer of the participant that publishes ``joint_states`` (at most
        :data:`GATE_WAIT_S`, then goes on with a warning: a plant that reports
        elsewhere).
        """
        topic, type_name = self._gate_topic  # type: ignore[misc]  # called only while a gate topic is set
        plants = _participants(self.get_publishers_info_by_topic(topic))
        if not plants:
            return
        reporters = _participants(self.get_publishers_info_by_topic(self.resolve_topic_name(DIAGNOSTICS.name)))
        unheard = sorted(plants[p] for p in plants.keys() - reporters.keys())
        self.waiting_for("joint_states gate", f"a /diagnostics writer of {', '.join(unheard)} (publisher of {topic}), "
                         "to hear the run's end" if unheard else None)
        if unheard and wall_time_s() - self._gate_since_s < GATE_WAIT_S:
            return
        if unheard:
            self.get_logger().warning(f"no /diagnostics writer of {unheard} after {GATE_WAIT_S} s: "
                                      "the run's end may go unheard")
            self.waiting_for("joint_states gate", None)
        self._gate_timer.cancel()
        self._subscribe(topic, type_name, LOCKSTEP_QOS)

    def _latched_arrived(self, topic: str) -> None:
        if topic in self._awaited:
            self._awaited.discard(topic)
            if not self._awaited:
                self._subscribe_per_tick()

    def _writer_for(self, topic: str, type_name: str) -> Any:
        wall_stamped = is_wall_stamped(type_name)

        def write(cdr: bytes) -> None:
            if wall_stamped:
                self.writer.write(topic, self.latest_sim_ns, cdr)
                self._watch_run_end(cdr)
                return
            stamp_ns = header_stamp_ns(cdr)
            self.latest_sim_ns = max(self.latest_sim_ns, stamp_ns)
            self.writer.write(topic, stamp_ns, cdr)
            self._latched_arrived(topic)

        return self.guarded(write)

    def _watch_run_end(self, cdr: bytes) -> None:
        from rclpy.serialization import deserialize_message

        for status in deserialize_message(cdr, DiagnosticArray).status:
            values = {kv.key: kv.value for kv in status.values}
            if status.message == RUN_FINISHED and TICKS_KEY in values and self._of_this_run(status, values):
                self.completion.ticks = int(values[TICKS_KEY])
                self.ended_at_s = wall_time_s()

    def _of_this_run(self, status: DiagnosticStatus, values: dict[str, str]) -> bool:
        """True for a status of a node of this run: its run id, else its node's namespace, is ours."""
        return values.get(RUN_ID_KEY, status.name.rpartition("/")[0] or "/") == self.get_namespace()

    def _check_done(self) -> None:
        counts = self.writer.message_counts
        if self.completion.complete(counts):
            self.finished = True
        elif self.ended_at_s is not None and wall_time_s() - self.ended_at_s > self.drain_timeout_s:
            self.fault(f"recorder: run ended but messages are missing after {self.drain_timeout_s} s: "
                       f"{self.completion.missing(counts)}")
        elif self.ended_at_s is None:
            self._check_plant_present(counts)

    def _check_plant_present(self, counts: dict[str, int]) -> None:
        """Fault (the bag is closed with what came) when the plant left the graph and its run end never came.

        Without this a recorder whose plant died, or whose "run finished" was
        lost, would wait for ever; the drain time lets a late report still land.
        """
        topic = self.resolve_topic_name(topics.JOINT_STATES.name)
        present = self.count_publishers(topic) > 0
        # Seen in the graph, or by its messages: a short run (or a loaded machine) may come and go between checks.
        self._plant_seen = self._plant_seen or present or counts.get(topic, 0) > 0
        if present or not self._plant_seen:
            self.plant_left_at_s = None
            return
        self.plant_left_at_s = self.plant_left_at_s or wall_time_s()
        if wall_time_s() - self.plant_left_at_s > self.drain_timeout_s:
            self.fault(f"recorder: the publisher of {topic} left the graph and no \"{RUN_FINISHED}\" of this run came "
                       f"on /diagnostics within {self.drain_timeout_s} s; the bag is closed with "
                       f"{counts.get(topic, 0)} {topic} messages")

    def destroy_node(self) -> None:
        """Close the bag (MCAP summary and metadata.yaml) on every way out."""
        self.writer.close()
        super().destroy_node()


def _participants(endpoints: list[Any]) -> dict[bytes, str]:
    """The DDS participants (the 12-byte GUID prefix of each endpoint's gid) of ``endpoints``, with a node name.

    By participant, not node name: an endpoint is discovered before its
    node's name is (``_NODE_NAME_UNKNOWN_`` meanwhile).
    """
    return {bytes(info.endpoint_gid[:12]): f"{info.node_namespace}/{info.node_name}" for info in endpoints}


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_tools recorder --ros-args -p output:=bags/run1``."""
    raise SystemExit(spin_node(RecorderNode, args))
