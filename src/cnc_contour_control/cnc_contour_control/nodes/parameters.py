"""Config classes as declared ROS parameters, and back: the ROS side of :mod:`cnc_contour_control.core.params`.

One parameter per config field, nested sections as dotted names (``gains.kp``,
as control_toolbox names its PID gains), each with a descriptor made from the
field's declaration: the description with its unit, a ``FloatingPointRange``
or ``IntegerRange`` from its range, read-only where a change needs a restart;
lists as typed arrays (double or string). The values are read back into a
mapping of the config's shape and built by the config's own ``build_config``
(or a node's builder around it), so the config's ``__post_init__`` stays the
one validation::

    run = declare_config(node, ServoRunParams)          # read-only parameters, built once
    params = ConfigParameters(node, build)              # a config that may change at run time
    params.add(Section(ServoConfig, skip=("axis_name", "law_params")))
    params.add(Section(law_config_class("pid"), "gains"))
    config = params.declare()                           # built (the config's error if invalid), then declared
    params.watch(apply)                                 # on-set validates a change, post-set applies it

:meth:`ConfigParameters.watch` follows the set-parameter pattern of
ros2/demos (jazzy): the on-set callback builds the config the change would
give and refuses the change with the config's error as the reason; the
post-set callback hands the new config to the node once the change is set.

Strings and YAML 1.1: rcl reads an unquoted ``y``, ``n``, ``yes``, ``no``,
``on``, ``off``, ``true`` or ``false`` as a boolean, so ``-p axis:=y``
arrives as ``true``. Every parameter is therefore first read with dynamic
typing and then declared with its static type: a string parameter given as a
boolean is the word written on the process's command line (``-p axis:=on``
is ``on``, :func:`command_line_words`); without one (a parameters file) an
axis name is the letter rcl took for one (``y`` or ``n``) and any other
string is refused with a line that says how to quote it; an integer given
for a float is that float.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Generic, TypeAlias, TypeVar

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from cnc_contour_control.core.config import build_config
from cnc_contour_control.core.errors import CncError, ConfigError
from cnc_contour_control.core.params import ParamSpec, flat_specs

C = TypeVar("C")
Type: TypeAlias = Parameter.Type

#: Parameters (last name part) that hold axis names: a YAML boolean there is the letter y or n.
AXIS_NAME_PARAMETERS = frozenset({"axis", "axes"})
_AXIS_LETTER = {True: "y", False: "n"}
#: The words rcl's YAML 1.1 reads as booleans (any case).
YAML_BOOLEAN_WORDS = {**dict.fromkeys(("y", "yes", "on", "true"), True),
                      **dict.fromkeys(("n", "no", "off", "false"), False)}
_SCALAR = {float: Type.DOUBLE, int: Type.INTEGER, bool: Type.BOOL, str: Type.STRING}
_ARRAY = {float: Type.DOUBLE_ARRAY, int: Type.INTEGER_ARRAY, bool: Type.BOOL_ARRAY, str: Type.STRING_ARRAY}
_INT64 = (-(2**63), 2**63 - 1)


@dataclass(frozen=True)
class Section:
    """A config class declared as parameters under ``prefix`` (``""``: top level; ``"gains"``: ``gains.kp``).

    Attributes
    ----------
    cls : type
        The config dataclass (fields declared with :func:`~cnc_contour_control.core.params.param`).
    prefix : str
        Dotted prefix of the parameter names.
    defaults : Mapping
        Start values by field name (dotted for nested fields) instead of the fields' defaults.
    skip : tuple of str
        Fields the node fills itself (not declared).
    unset : bool
        Declare every field without a value (an optional override: only what is given counts).
    read_only : bool
        Every field read-only, whatever its declaration says (a section read once at start).
    """

    cls: type
    prefix: str = ""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    skip: tuple[str, ...] = ()
    unset: bool = False
    read_only: bool = False

    def parameters(self) -> list[tuple[str, ParamSpec, Any]]:
        """(parameter name, spec, start value) of every declared field."""
        head = f"{self.prefix}." if self.prefix else ""
        return [(head + s.name, s, None if self.unset else self.defaults.get(s.name, s.default))
                for s in flat_specs(self.cls) if s.name.split(".")[0] not in self.skip]


def ros_type(spec: ParamSpec, default: Any) -> Type:
    """The ROS parameter type of a field (a list's element type from its default: float if none)."""
    if spec.kind is list:
        items = list(default or ()) or list(spec.default or ())
        return _ARRAY[type(items[0]) if items and type(items[0]) in _ARRAY else float]
    if spec.kind in _SCALAR:
        return _SCALAR[spec.kind]
    raise TypeError(f"{spec.name}: a free mapping is not a ROS parameter; skip it or give it a config class")


def descriptor(spec: ParamSpec, kind: Type, read_only: bool = False) -> ParameterDescriptor:
    """The descriptor of a field: description with unit, range (scalars), read-only (or ``read_only``), type."""
    result = ParameterDescriptor(description=spec.description, read_only=spec.info.read_only or read_only,
                                 type=kind.value)
    low, high = spec.info.low, spec.info.high
    if low is None and high is None:
        return result
    if kind == Type.DOUBLE:
        result.floating_point_range = [FloatingPointRange(
            from_value=-math.inf if low is None else float(low), to_value=math.inf if high is None else float(high),
            step=0.0)]
    elif kind == Type.INTEGER:
        result.integer_range = [IntegerRange(
            from_value=_INT64[0] if low is None else math.ceil(low),
            to_value=_INT64[1] if high is None else math.floor(high), step=0)]
    return result


def ros_value(kind: Type, value: Any) -> Any:
    """A config value as a ROS parameter value of type ``kind`` (tuples as lists, ints as floats)."""
    if value is None:
        return None
    if kind == Type.DOUBLE_ARRAY:
        return [float(v) for v in value]
    if kind in (Type.STRING_ARRAY, Type.INTEGER_ARRAY, Type.BOOL_ARRAY):
        return list(value)
    if kind == Type.DOUBLE and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def plain(value: Any) -> Any:
    """A parameter value as plain Python (rclpy gives numeric arrays as ``array.array``)."""
    return list(value) if value is not None and not isinstance(value, (str, bytes, bool, int, float)) else value


def command_line_words(argv: Sequence[str], node_name: str) -> dict[str, str]:
    """The text of every ``-p NAME:=VALUE`` (``--param``) in the ROS arguments of ``argv``, by name.

    ``-p NODE:NAME:=VALUE`` counts only for the node called ``node_name``.
    """
    words: dict[str, str] = {}
    ros = False
    for index, arg in enumerate(argv):
        if arg in ("--ros-args", "--"):
            ros = arg == "--ros-args"
        elif ros and arg in ("-p", "--param") and index + 1 < len(argv) and ":=" in argv[index + 1]:
            target, _, value = argv[index + 1].partition(":=")
            node, _, name = target.rpartition(":")
            if node in ("", node_name):
                words[name] = value
    return words


def command_line_rules(argv: Sequence[str]) -> list[str]:
    """Every ``-p RULE`` (``--param``) in the ROS arguments of ``argv``, as written (``NAME:=VALUE``)."""
    rules: list[str] = []
    ros = False
    for index, arg in enumerate(argv):
        if arg in ("--ros-args", "--"):
            ros = arg == "--ros-args"
        elif ros and arg in ("-p", "--param") and index + 1 < len(argv) and ":=" in argv[index + 1]:
            rules.append(argv[index + 1])
    return rules


def given_value(name: str, kind: Type, value: Any, word: str | None = None) -> Any:
    """A value given for parameter ``name`` as type ``kind`` where that loses nothing; else unchanged.

    Integers become floats for a double (array). A boolean where a string
    belongs is rcl's reading of an unquoted YAML 1.1 word: the ``word`` as
    written on the command line if there is one, else for an axis name the
    letter (``y``/``n``), for any other string a :class:`ConfigError` that says
    how to quote it.
    """
    value = plain(value)
    if value is None:
        return None
    if kind == Type.DOUBLE and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if kind == Type.DOUBLE_ARRAY and isinstance(value, list) and all(_is_int(v) for v in value):
        return [float(v) for v in value]
    if kind == Type.STRING and isinstance(value, bool):
        if word is not None and YAML_BOOLEAN_WORDS.get(word.lower()) is value:
            return word
        return _string_from_boolean(name, value)
    if kind == Type.STRING_ARRAY and isinstance(value, list) and all(isinstance(v, bool) for v in value):
        return [_string_from_boolean(name, v) for v in value]
    return value


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _string_from_boolean(name: str, value: bool) -> str:
    if name.rsplit(".", 1)[-1] in AXIS_NAME_PARAMETERS:
        return _AXIS_LETTER[value]
    raise ConfigError(
        f"{name} must be a string, got the boolean {str(value).lower()}: rcl's YAML 1.1 reads an unquoted "
        f"y, n, yes, no, on, off, true or false as a boolean; quote it (-p {name}:=\"'...'\")")


def nested(values: Mapping[str, Any]) -> dict[str, Any]:
    """Flat dotted names -> a nested mapping (``{"gains.kp": 1}`` -> ``{"gains": {"kp": 1}}``); unset values left
    out."""
    out: dict[str, Any] = {}
    for name, value in values.items():
        if value is None:
            continue
        *parents, leaf = name.split(".")
        level = out
        for part in parents:
            level = level.setdefault(part, {})
        level[leaf] = value
    return out


def _probe(node: Node, name: str, default: Any) -> Any:
    """The value given for ``name`` (or ``default``), read with dynamic typing; the parameter is undeclared again."""
    value = node.declare_parameter(name, default, ParameterDescriptor(dynamic_typing=True)).value
    node.undeclare_parameter(name)
    return value


def _declare(node: Node, name: str, kind: Type, value: Any, desc: ParameterDescriptor) -> None:
    """Declare ``name`` statically typed with its descriptor and the (already validated) ``value``.

    An empty list is declared typed but unset: rcl cannot tell an empty
    array's element type (the config reads it as its empty default).
    """
    if isinstance(value, list) and not value:
        value = None
    if value is not None and Type.from_parameter_value(value) != kind:
        raise ConfigError(f"{name} must be a {kind.name.lower().replace('_', ' ')}, got {value!r}")
    try:
        node.declare_parameter(name, kind if value is None else value, desc, ignore_override=True)
    except (InvalidParameterTypeException, InvalidParameterValueException) as err:
        raise ConfigError(f"{name}: {err}") from err


class ConfigParameters(Generic[C]):
    """The parameters of one config on a node: read, built, declared, then kept valid on every change.

    Parameters
    ----------
    node : Node
        The node that declares them.
    build : callable
        Nested mapping of the values (the sections' shape) -> validated config;
        raises a :class:`~cnc_contour_control.core.errors.CncError` for a bad value.
    """

    def __init__(self, node: Node, build: Callable[[dict[str, Any]], C]) -> None:
        self.node = node
        self.build = build
        self.values: dict[str, Any] = {}
        self._declared: dict[str, tuple[Type, ParameterDescriptor]] = {}
        self._apply: Callable[[C], None] | None = None
        self.config: C | None = None
        self._words = command_line_words(sys.argv, node.get_name())  # the process's -p NAME:=VALUE, as written

    def add(self, section: Section) -> dict[str, Any]:
        """Read the section's parameters (the given value or the start value); their values by parameter name."""
        read = {}
        for name, spec, start in section.parameters():
            kind = ros_type(spec, start)
            read[name] = given_value(name, kind, _probe(self.node, name, ros_value(kind, start)), self._words.get(name))
            self._declared[name] = (kind, descriptor(spec, kind, section.read_only))
        self.values.update(read)
        return read

    def declare(self) -> C:
        """Build the config from the values read (the config's error if one is invalid), then declare them all."""
        self.config = self.build(nested(self.values))
        for name, (kind, desc) in self._declared.items():
            _declare(self.node, name, kind, self.values[name], desc)
        return self.config

    def watch(self, apply: Callable[[C], None]) -> None:
        """Validate every change in an on-set callback; hand the new config to ``apply`` after it is set.

        A pre-set callback first gives a change the declared type where that
        loses nothing (``ros2 param set /cnc/servo_x gains.kp 3`` sets 3.0).
        """
        self._apply = apply
        self.node.add_pre_set_parameters_callback(self._pre_set)
        self.node.add_on_set_parameters_callback(self._on_set)
        self.node.add_post_set_parameters_callback(self._post_set)

    def _changes(self, parameters: Sequence[Parameter]) -> dict[str, Any]:
        return {p.name: plain(p.value) for p in parameters if p.name in self._declared}

    def _pre_set(self, parameters: list[Parameter]) -> list[Parameter]:
        """The change with integers as floats for double parameters (and int arrays as double arrays)."""
        return [self._typed(p) for p in parameters]

    def _typed(self, parameter: Parameter) -> Parameter:
        if parameter.name not in self._declared or parameter.type_ not in (Type.INTEGER, Type.INTEGER_ARRAY):
            return parameter
        kind = self._declared[parameter.name][0]
        value = given_value(parameter.name, kind, parameter.value)
        return Parameter(parameter.name, kind, value) if kind in (Type.DOUBLE, Type.DOUBLE_ARRAY) else parameter

    def _on_set(self, parameters: list[Parameter]) -> SetParametersResult:
        """Refuse a change whose config would not build, with the config's error as the reason."""
        changes = self._changes(parameters)
        if changes:
            try:
                self.build(nested({**self.values, **changes}))
            except CncError as err:
                return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _post_set(self, parameters: list[Parameter]) -> None:
        """Take the change (validated on set) and hand the new config to the node."""
        changes = self._changes(parameters)
        if changes and self._apply is not None:
            self.values.update(changes)
            self.config = self.build(nested(self.values))
            self._apply(self.config)


def declare_config(node: Node, cls: type[C], prefix: str = "", defaults: Mapping[str, Any] | None = None) -> C:
    """Declare the fields of ``cls`` as parameters of ``node`` and return the config they build (``build_config``)."""
    params: ConfigParameters[C] = ConfigParameters(node, lambda mapping: build_config(
        cls, section_values(mapping, prefix), context=prefix))
    params.add(Section(cls, prefix, defaults or {}))
    return params.declare()


def section_values(mapping: Mapping[str, Any], prefix: str) -> dict[str, Any]:
    """The part of a nested mapping under a dotted ``prefix`` (all of it for ``""``; empty if absent)."""
    for part in prefix.split(".") if prefix else ():
        mapping = mapping.get(part, {})
    return dict(mapping)
