"""Refused messages of an outside topic (an operator's, a planner's), counted and reported on ``/diagnostics``.

A message from outside the lockstep loop (a feed override, a joint
trajectory) that is malformed is refused and the machine goes on: the node
keeps what it had. Each refusal is counted; the first, and then at most one a
``period_s`` of wall time, is published WARN on ``/diagnostics`` with the topic,
the count and the reason (never ERROR: a refusal is no fault) and logged.
"""
from __future__ import annotations

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus

from cnc_contour_control.nodes.common import wall_time_s

#: Wall time between two reports of one topic's refusals, s.
REPORT_PERIOD_S = 1.0


class RefusalCounter:
    """Counts the refused messages of ``topic`` on ``node`` (a SuiteNode) and reports them, throttled."""

    def __init__(self, node: Any, topic: str, period_s: float = REPORT_PERIOD_S) -> None:
        self.node, self.topic, self.period_s = node, node.resolve_topic_name(topic), period_s
        self.count = 0
        self._reported_s = -float("inf")

    def refuse(self, reason: str) -> None:
        """Count one refused message; report it now unless one was reported within ``period_s``."""
        self.count += 1
        now_s = wall_time_s()
        if now_s - self._reported_s < self.period_s:
            return
        self._reported_s = now_s
        message = f"{self.topic}: message refused ({self.count} so far): {reason}"
        self.node.get_logger().warning(message)
        self.node.report(DiagnosticStatus.WARN, message,
                         {"topic": self.topic, "refused_count": str(self.count), "reason": reason})
