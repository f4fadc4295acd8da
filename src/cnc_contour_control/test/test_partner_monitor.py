"""PartnerMonitor looks cheaply: a publisher count per topic each look, names only when the count changed."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from cnc_contour_control.nodes.safety_io import UNKNOWN_NODE, PartnerMonitor

TOPIC = "/cnc/reference"


class FakeGraph:
    """A node's graph queries over a list of (namespace, name) publishers of ``TOPIC``; counts the name queries."""

    def __init__(self) -> None:
        self.publishers: list[tuple[str, str]] = [("/cnc", "interpolator")]
        self.info_calls = 0

    def resolve_topic_name(self, topic: str) -> str:
        return topic

    def create_timer(self, period_s: float, callback: Any) -> None:
        assert period_s > 0

    def guarded(self, callback: Any) -> Any:
        return callback

    def count_publishers(self, topic: str) -> int:
        return len(self.publishers) if topic == TOPIC else 0

    def get_publishers_info_by_topic(self, topic: str) -> list[SimpleNamespace]:
        self.info_calls += 1
        return [SimpleNamespace(node_namespace=ns, node_name=name) for ns, name in self.publishers]


def _monitor(graph: FakeGraph, losses: list[str]) -> PartnerMonitor:
    return PartnerMonitor(graph, [TOPIC], lambda: True, losses.append, lambda: 2_000_000_000)  # type: ignore[arg-type]  # a stand-in graph


def test_names_are_read_once_while_the_count_stays_and_a_loss_names_the_last_publisher() -> None:
    graph, losses = FakeGraph(), []
    monitor = _monitor(graph, losses)
    for _ in range(50):
        monitor.check()
    assert graph.info_calls == 1 and not losses
    graph.publishers = []
    monitor.check()
    assert not losses, "one empty look may be a starved graph query"
    monitor.check()
    assert graph.info_calls == 1
    assert losses == ["/cnc/interpolator left the graph: /cnc/reference has 0 publishers (had 1) at t=2.000000 s"]


def test_a_changed_count_or_an_unnamed_publisher_reads_the_names_again() -> None:
    graph, losses = FakeGraph(), []
    monitor = _monitor(graph, losses)
    graph.publishers = [("/cnc", UNKNOWN_NODE)]
    monitor.check()
    monitor.check()
    assert graph.info_calls == 2  # not named yet: asked again at each look
    graph.publishers = [("/cnc", "interpolator")]
    monitor.check()
    monitor.check()
    assert graph.info_calls == 3
    graph.publishers.append(("/cnc", "other"))
    monitor.check()
    assert graph.info_calls == 4
    assert monitor.last_publishers(TOPIC) == " (last published by /cnc/interpolator, /cnc/other)"
    assert not losses
