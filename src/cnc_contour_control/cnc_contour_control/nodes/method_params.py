"""A stage chosen by name from a registry, with that entry's config as nested parameters (``params.*``)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node

from cnc_contour_control.nodes.parameters import ConfigParameters, Section

#: The nested parameters holding the chosen method's config fields.
METHOD_PARAMS = "params"


def method_parameters(node: Node, settings: type, config_class_of: Callable[[str], type]) -> ConfigParameters[Any]:
    """``settings``' fields as parameters, and the chosen ``method``'s config fields as ``params.<field>``.

    The method is read first (a parameter like any other, read-only); its
    config class (``config_class_of(method)``) gives the nested parameters.
    """
    parameters: ConfigParameters[Any] = ConfigParameters(
        node, lambda mapping: settings.from_mapping(mapping, context=node.get_name()))  # type: ignore[attr-defined]  # a settings class
    method = parameters.add(Section(settings, skip=(METHOD_PARAMS,)))["method"]
    parameters.add(Section(config_class_of(method), METHOD_PARAMS))
    return parameters
