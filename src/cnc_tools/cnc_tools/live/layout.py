"""The Foxglove layout shipped with the suite (``layout.json`` beside this module), built with ``foxglove.layouts``.

Left: the XY plot of position against the reference at 1:1 (locked scales) and the 3D scene; right: the contour
error (exact and estimated peaks), each axis's following error (peaks), the feed override requested and applied,
and the log. Every topic it names is a channel the live server advertises (``test_live`` checks it).
``python -m cnc_tools.live.layout`` writes the file again.
"""
from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

LAYOUT_PATH = Path(__file__).resolve().parent / "layout.json"
#: Axes whose following error is plotted.
PLOTTED_AXES = ("x", "y")


def build_layout() -> dict[str, Any]:
    """The layout as a JSON object."""
    import foxglove.layouts as fl

    def plot(title: str, *series: tuple[str, str]) -> Any:
        paths = [fl.PlotSeries(value=value, label=label, timestamp_method="receiveTime") for value, label in series]
        return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=paths, show_legend=True, x_axis_val="timestamp"))

    xy = fl.PlotPanel(title="XY: position against the reference, mm (1:1)", config=fl.PlotConfig(
        paths=[fl.PlotSeries(value="/live/xy.ref_y_mm", x_value_path="/live/xy.ref_x_mm", label="reference"),
               fl.PlotSeries(value="/live/xy.y_mm", x_value_path="/live/xy.x_mm", label="position")],
        x_axis_val="custom", x_axis_path=fl.PlotXAxisPath(value="/live/xy.x_mm"), axis_scales_mode="lockedScales",
        show_legend=True, x_axis_label="x [mm]", y_axis_label="y [mm]"))
    scene = fl.ThreeDeePanel(title="program and tool trail", config=fl.ThreeDeeConfig(
        follow_tf="machine", fixed_frame="machine",
        topics={"/live/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True)}))
    errors = plot("contour error, um (peaks)", ("/live/contour_error/exact/peaks.contour_error_um", "exact"),
                  ("/live/contour_error/estimated/peaks.contour_error_um", "estimated"))
    following = plot("following error, um (peaks)", *((f"/live/servo/{axis}/peaks.following_error_um", axis)
                                                      for axis in PLOTTED_AXES))
    override = plot("feed override", ("/live/feed_override.requested_ratio", "requested"),
                    ("/live/feed_override.applied_ratio", "applied"))
    log = fl.LogPanel(title="faults and diagnostics", config=fl.LogConfig(topic_to_render="/live/log"))
    left = fl.SplitContainer(direction="column", items=[fl.SplitItem(proportion=3, content=xy),
                                                        fl.SplitItem(proportion=2, content=scene)])
    right = fl.SplitContainer(direction="column", items=[fl.SplitItem(content=panel)
                                                         for panel in (errors, following, override, log)])
    layout = fl.Layout(content=fl.SplitContainer(direction="row", items=[fl.SplitItem(content=left),
                                                                        fl.SplitItem(content=right)]))
    return dict(json.loads(layout.to_json()))


def layout_topics(layout: Any) -> set[str]:
    """Every channel a layout names (``/topic.field`` paths and ``topic_to_render``-style values)."""
    found: set[str] = set()
    if isinstance(layout, dict):
        for value in layout.values():
            found |= layout_topics(value)
    elif isinstance(layout, list):
        for value in layout:
            found |= layout_topics(value)
    elif isinstance(layout, str) and (match := re.fullmatch(r"(/[\w/]+?)(\.\w+)?", layout)):
        found.add(match.group(1))
    return found


def write_layout(path: Path = LAYOUT_PATH) -> Path:
    """Write the layout file (indented JSON)."""
    path.write_text(json.dumps(build_layout(), indent=2) + "\n", encoding="utf-8")
    return path


if __name__ == "__main__":
    print(write_layout())
