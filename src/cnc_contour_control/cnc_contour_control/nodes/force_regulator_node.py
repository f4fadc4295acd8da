"""Force-regulator node: ``cutting_force`` -> ``feed_override`` every tick (paper 004).

Thin: each force sample is checked, handed to the core
:class:`~cnc_contour_control.force.ForceRegulator` with dt from the stamps (the
nominal period at the first tick), and its override published with the
force's stamp; the interpolator takes it at the next tick (its
``previous_tick`` source). Parameters: :class:`LockstepInputs`,
:class:`~cnc_contour_control.force.settings.ForceSetpoint` (``reference_n``,
``stale_timeout_s``), :class:`~cnc_contour_control.force.ForceRegulatorConfig`
(``law``, ``update_period_s``, ``quantiser.*``), the law's config as
``law_params.*`` and the program's depth schedule for the preview as
``preview.*`` (:class:`~cnc_contour_control.force.preview_settings.PreviewSettings`), all read
once. A non-finite force is a fault naming the value; a force that stops
arriving for ``stale_timeout_s`` (wall time) is a
STALE status on ``/diagnostics`` while the last applied override holds (no new
message: the interpolator keeps the latest), and an OK status when it is back.
"""
from __future__ import annotations

import math
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped

from cnc_contour_control.core.config import build_config, require_choice
from cnc_contour_control.core.errors import FaultError
from cnc_contour_control.core.lockstep import NS_PER_S, StampMatcher, seconds_to_ns, stamp_horizon_ns
from cnc_contour_control.core.topics import DIAGNOSTICS, RUN_FINISHED, RUN_ID_KEY
from cnc_contour_control.force import FORCE_LAWS, ForceRegulator, ForceRegulatorConfig, OverrideSample
from cnc_contour_control.force.preview_settings import PreviewSettings
from cnc_contour_control.force.settings import PREVIEW, ForceSetpoint
from cnc_contour_control.graph.stage_params import LockstepInputs
from cnc_contour_control.nodes.common import SuiteNode, ns_to_stamp, spin_node, wall_time_s
from cnc_contour_control.nodes.parameters import ConfigParameters, Section, declare_config
from cnc_contour_interfaces.msg import FeedOverride

#: The nested parameters holding the law's config fields.
LAW_PARAMS = "law_params"
#: The topic the node reads and the field that carries F_c.
FORCE_TOPIC, FORCE_FIELD = "cutting_force", "cutting_force.wrench.force.x"


def regulator_parameters(node: SuiteNode) -> ConfigParameters[ForceRegulatorConfig]:
    """ForceRegulatorConfig's fields as read-only parameters, the chosen law's config as ``law_params.*``."""
    parameters: ConfigParameters[ForceRegulatorConfig] = ConfigParameters(
        node, lambda mapping: build_config(ForceRegulatorConfig, mapping, context="force_regulator"))
    law = parameters.add(Section(ForceRegulatorConfig, skip=(LAW_PARAMS,), read_only=True))["law"]
    parameters.add(Section(FORCE_LAWS[require_choice("law", law, FORCE_LAWS)].config_class, LAW_PARAMS,
                           read_only=True))
    return parameters


def force_of(msg: WrenchStamped) -> float:
    """F_c [N] of a ``cutting_force`` message (``force.x``, tool frame); a non-finite value is a fault naming it."""
    value = float(msg.wrench.force.x)
    if not math.isfinite(value):
        raise FaultError(f"{FORCE_FIELD} must be finite, got {value!r}")
    return value


def override_msg(sample: OverrideSample, quantum: float, stamp_ns: int) -> FeedOverride:
    """One regulator output as the ``feed_override`` message of tick ``stamp_ns``."""
    msg = FeedOverride(requested_ratio=float(sample.requested_ratio), applied_ratio=float(sample.applied_ratio),
                       quantum=float(quantum))
    msg.header.stamp = ns_to_stamp(stamp_ns)
    return msg


class ForceRegulatorNode(SuiteNode):
    """Publishes ``feed_override`` for every ``cutting_force`` sample, in lockstep."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("force_regulator", **kwargs)
        run = declare_config(self, LockstepInputs)
        self.setpoint = declare_config(self, ForceSetpoint)
        config = regulator_parameters(self).declare()
        preview = declare_config(self, PreviewSettings, PREVIEW)
        self.regulator = ForceRegulator(config, preview.plans(self.setpoint.reference_n, config))
        self.sample_time_ns = seconds_to_ns(run.sample_time_s)
        self.matcher = StampMatcher((FORCE_TOPIC,), run.input_timeout_s, run.startup_timeout_s,
                                    stamp_horizon_ns(self.sample_time_ns))
        self.last_stamp_ns: int | None = None
        self.last_force_wall_s: float | None = None
        self.stale = False
        self.run_over = False
        self.publisher = self.gated_publisher(FeedOverride, "feed_override", 1)
        self.subscribe_matched(self.matcher, WrenchStamped, FORCE_TOPIC, force_of, self._step)
        self.create_subscription(DiagnosticArray, DIAGNOSTICS.name, self.guarded(self._watch_run_end), 100)
        self.create_timer(0.1, self.guarded(self._watch_stale))

    def _step(self, items: dict[str, Any]) -> None:
        stamp_ns = self.matcher.last_released_ns
        assert stamp_ns is not None  # a tick was just released
        dt_ns = self.sample_time_ns if self.last_stamp_ns is None else stamp_ns - self.last_stamp_ns
        sample = self.regulator.step(dt_ns / NS_PER_S, items[FORCE_TOPIC], self.setpoint.reference_n)
        self.last_stamp_ns, self.last_force_wall_s = stamp_ns, wall_time_s()
        self.publisher.publish(override_msg(sample, self.regulator.config.quantiser.step_ratio, stamp_ns))
        if self.stale:
            self.stale = False
            self.report(DiagnosticStatus.OK, "force_regulator: cutting_force is back")

    def _watch_stale(self) -> None:
        """After ``stale_timeout_s`` without a force: STALE once, the last applied override held."""
        if self.stale or self.run_over or self.last_force_wall_s is None:
            return
        idle_s = wall_time_s() - self.last_force_wall_s
        if idle_s > self.setpoint.stale_timeout_s:
            self.stale = True
            applied = self.regulator.last.applied_ratio
            self.report(DiagnosticStatus.STALE,
                        f"force_regulator: no {self.resolve_topic_name(FORCE_TOPIC)} for {idle_s:.2f} s "
                        f"(stale_timeout_s {self.setpoint.stale_timeout_s}); holding the applied override {applied}",
                        {"applied_ratio": repr(applied)})

    def _watch_run_end(self, msg: DiagnosticArray) -> None:
        """The plant's end of this run: the force stops by design, nothing is stale."""
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.message == RUN_FINISHED and values.get(RUN_ID_KEY) == self.get_namespace():
                self.run_over = True


def main(args: list[str] | None = None) -> None:
    """Entry point: ``ros2 run cnc_contour_control force_regulator --ros-args -p reference_n:=500.0``."""
    raise SystemExit(spin_node(ForceRegulatorNode, args))
