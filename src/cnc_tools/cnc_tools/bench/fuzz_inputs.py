"""The four input kinds of ``bench fuzz``: each a seeded generator and a check of one input.

A check returns ``None`` when the input was refused with a :class:`CncError`,
``""`` when it was accepted and is sensible, else a phrase saying which
nonsense was accepted.
Any other exception escapes it: the bench counts it as a traceback. What
"nonsense" means per kind:

- ``gcode``: a program accepted with a non-finite number or a feed <= 0 in it,
  or accepted although a line holds a word the reader does not know (a letter
  other than the axes, I/J/K, F, P, R, S, T, G, M, N);
- ``scenario``: a scenario accepted with NaN or infinity in a numeric key, a
  bool, string, list or mapping where a number was, a value <= 0 in a key that
  must be positive, or a key the format does not have;
- ``messages``: a decode function of a node that returns for a message with a
  non-finite value it reads, a missing or repeated axis, or an array whose
  length differs from its names, or returns another value than the message holds;
- ``bag``: a damaged bag judged complete, or a sample read from it that the
  intact bag does not hold.
"""
from __future__ import annotations

import math
import random
import string
from collections.abc import Callable, Sequence
from copy import deepcopy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_contour_control.core.errors import CncError
from cnc_contour_control.motion.gcode import parse_gcode
from cnc_contour_control.motion.gcode_file import decode_gcode
from cnc_contour_control.motion.geometry import ArcSegment, Program

#: Letters the G-code reader knows for a 2-axis (x, y) program.
KNOWN_LETTERS = frozenset("XYIJKFPRSTGMN")
#: Scenario keys whose values must be > 0.
POSITIVE_KEYS = frozenset({
    "sample_time_s", "duration_s", "radius_mm", "feed_mm_min", "max_velocity_mm_min", "max_acceleration_mm_s2",
    "counts_per_m", "output_limit", "leg_mm", "length_mm", "time_constant_s", "tool_diameter_mm", "flutes",
    "update_period_s", "max_ratio"})
#: Scenario sections that are free text for people, not read by the suite.
FREE_KEYS = frozenset({"name", "description", "paper"})


# =========================================================================== G-code
_VALUES = ("0", "1", "-1", "10", "25.4", ".5", "-.5", "1.", "+3", "0.000001", "99999", "9" * 40, "9" * 400,
           "-" + "9" * 400, "1" + "0" * 320, ".", "-", "")
_G_WORDS = ("G0", "G1", "G2", "G3", "G4", "G17", "G18", "G19", "G20", "G21", "G54", "G59", "G61", "G64", "G90",
            "G91", "G90.1", "G91.1", "G93", "G94", "G99", "G1.5", "G-1", "M2", "M30", "M3", "M0.5")


def _word(rng: random.Random) -> str:
    letter = rng.choice("XYIJKFPRXYXYFZABCDEHLOQUVWxyfij")
    return letter + rng.choice(_VALUES)


def _token_soup(rng: random.Random) -> str:
    pieces = [rng.choice((*_G_WORDS, _word(rng), _word(rng), "(", ")", "(note)", ";", "%", " ", "\n", "\n",
                          "\t", "é", "١", "\x00", "e5", "N10"))
              for _ in range(rng.randint(1, 40))]
    return "".join(pieces)


_PROGRAM = ("G21 G90 G17", "F600", "G1 X10 Y0", "G3 X0 Y10 I-10 J0", "G2 X10 Y0 R10", "G4 P0.5",
            "G64 P0.01", "G1 X0 Y0", "M30")


def _mutated_program(rng: random.Random) -> tuple[str, bool]:
    """A valid program with a few words or values changed; True when an unknown word was put in."""
    lines = [line.split() for line in _PROGRAM]
    for _ in range(rng.randint(1, 3)):
        line = rng.choice(lines[:-1])
        at = rng.randrange(len(line))
        what = rng.random()
        if what < 0.3:
            line[at] = line[at][0] + rng.choice(_VALUES)
        elif what < 0.6:
            letter = rng.choice(string.ascii_uppercase)
            line.insert(at, letter + rng.choice(("1", "2.5", "-3")))
        else:
            line[at] = rng.choice((*_G_WORDS, _word(rng)))
    unknown = any(word[0].upper() not in KNOWN_LETTERS for line in lines for word in line if word)
    return "\n".join(" ".join(line) for line in lines), unknown


def gcode_input(rng: random.Random) -> tuple[str, bool]:
    """(program text, whether it holds an unknown word for certain): token soup, a mutated program, or bytes."""
    choice = rng.random()
    if choice < 0.4:
        return _token_soup(rng), False
    if choice < 0.8:
        return _mutated_program(rng)
    data = bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 200)))
    try:
        return decode_gcode(data), False
    except CncError:
        return "\x00", False


def _program_numbers(program: Program) -> list[float]:
    numbers: list[float] = []
    for seg in program.segments:
        numbers += [*np.ravel(seg.start_m), *np.ravel(seg.end_m), seg.feed_m_s, seg.length_m]
        if isinstance(seg, ArcSegment):
            numbers += list(np.ravel(seg.center_m))
    numbers += [d.duration_s for d in program.dwells]
    return numbers


def check_gcode(case: tuple[str, bool]) -> str | None:
    """Parse the text as a 2-axis program; the nonsense it was accepted with, if any."""
    text, unknown = case
    try:
        program = parse_gcode(text, ("x", "y"))
    except CncError:
        return None
    if unknown:
        return f"unknown word accepted in {text!r}"
    numbers = _program_numbers(program)
    if not all(math.isfinite(v) for v in numbers):
        return f"non-finite number accepted from {text!r}"
    if any(seg.feed_m_s <= 0.0 for seg in program.segments):
        return f"feed <= 0 accepted from {text!r}"
    return ""


# =========================================================================== scenarios
def _scenario_bases() -> list[tuple[dict[str, Any], Path]]:
    """The shipped scenarios that load, as raw mappings (read once)."""
    from ruamel.yaml import YAML

    from cnc_tools.runs.scenario import build_scenario

    root = Path(__file__).resolve().parents[4] / "scenarios"
    bases = []
    for path in sorted(root.glob("*.yaml")):
        raw = YAML(typ="safe").load(path.read_text(encoding="utf-8"))
        try:
            build_scenario(raw, base_dir=path.parent, source=path)
        except CncError:
            continue
        bases.append((raw, path.parent))
    return bases


_BASES: list[tuple[dict[str, Any], Path]] = []


def _leaves(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _leaves(v, (*path, k))] + [(*path, None)]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _leaves(v, (*path, i))]
    return [path]


def _bad_value(rng: random.Random, old: Any, key: Any) -> tuple[Any, str | None]:
    """A replacement for a leaf and, when it is nonsense for that key, why."""
    numeric = isinstance(old, (int, float)) and not isinstance(old, bool)
    choices: list[tuple[Any, str | None]] = [
        (math.nan, "NaN" if numeric else None), (math.inf, "infinity" if numeric else None),
        (-math.inf, "-infinity" if numeric else None), (True, "a bool for a number" if numeric else None),
        ("abc", "a string for a number" if numeric else None), ({"a": 1}, "a mapping for a scalar"),
        (1e300, None), (0, None), (rng.choice((-1, -0.5, -1e9)), None), (None, None)]
    value, why = rng.choice(choices)
    if numeric and key in POSITIVE_KEYS and isinstance(value, (int, float)) and not isinstance(value, bool) \
            and value <= 0:
        why = f"{value} for a positive key"
    return value, why


def scenario_input(rng: random.Random) -> tuple[dict[str, Any], Path, str | None]:
    """(raw scenario, its folder, why it is nonsense or None): a shipped scenario with one or two keys changed."""
    if not _BASES:
        _BASES.extend(_scenario_bases())
    base, folder = rng.choice(_BASES)
    raw, why = deepcopy(base), None
    changed: list[tuple[Any, ...]] = []
    for _ in range(rng.randint(1, 2)):
        path = rng.choice([p for p in _leaves(raw) if not any(p[:len(c)] == c for c in changed)])
        changed.append(path)
        parent = raw
        for step in path[:-1]:
            parent = parent[step]
        free = any(step in FREE_KEYS for step in path if isinstance(step, str))
        if path[-1] is None:                      # a new key in this mapping
            parent[rng.choice(("colour", "sample_time", "kp2", "radius_m"))] = 1.0
            why = why or (None if free else "an unknown key")
        else:
            value, bad = _bad_value(rng, parent[path[-1]], path[-1])
            parent[path[-1]] = value
            why = why or (None if free else bad and f"{bad} at {'.'.join(map(str, path))}")
    return raw, folder, why


def check_scenario(case: tuple[dict[str, Any], Path, str | None]) -> str | None:
    """Build the scenario; the nonsense it was accepted with, if any."""
    from cnc_tools.runs.scenario import build_scenario

    raw, folder, why = case
    try:
        build_scenario(raw, base_dir=folder)
    except CncError:
        return None
    return f"scenario accepted with {why}" if why else ""


# =========================================================================== messages
@dataclass(frozen=True)
class MessageCase:
    """A decode function, the message given to it, and what a sensible decode returns (None: refuse)."""

    name: str
    call: Callable[[], Any]
    expected: Any
    message: str = ""


_AXES = ("x", "y")
_BAD_FLOATS = (math.nan, math.inf, -math.inf)


def _names(rng: random.Random) -> list[str]:
    return list(rng.choice((_AXES, _AXES, _AXES, ("y", "x"), ("x",), ("x", "y", "z"), ("x", "x"), (), ("x", "q"))))


def _values(rng: random.Random, n: int) -> list[float]:
    values = [rng.uniform(-1.0, 1.0) for _ in range(max(n + rng.choice((0, 0, 0, 0, 1, -1)), 0))]
    if values and rng.random() < 0.4:
        values[rng.randrange(len(values))] = rng.choice(_BAD_FLOATS)
    return values


def _lookup(names: Sequence[str], arrays: Sequence[Sequence[float]], axis: str) -> Any:
    """The sensible single-axis read: None when the axis is missing or repeated, a length differs, or non-finite."""
    if names.count(axis) != 1 or any(len(a) != len(names) for a in arrays):
        return None
    values = tuple(float(a[names.index(axis)]) for a in arrays)
    return values if all(math.isfinite(v) for v in values) else None


def _all_axes(names: Sequence[str], arrays: Sequence[Sequence[float]]) -> Any:
    """The sensible all-axes read (names exactly the run's axes, in order)."""
    if tuple(names) != _AXES or any(len(a) != len(names) for a in arrays):
        return None
    values = [[float(v) for v in a] for a in arrays]
    return values if all(math.isfinite(v) for a in values for v in a) else None


def message_input(rng: random.Random) -> MessageCase:
    """A generated message for one of the decode functions of the control and plant nodes."""
    from sensor_msgs.msg import JointState

    from cnc_contour_control.nodes import conversions as control
    from cnc_contour_interfaces.msg import AxisCommand, Compensation, ContourError, Reference
    from cnc_plant_sim.nodes import conversions as plant

    names, axis = _names(rng), rng.choice(("x", "y"))
    kind = rng.randrange(9)
    if kind == 8:
        field = rng.choice(("effort", "velocity"))
        cmd_msg = JointState(name=names, **{field: _values(rng, len(names))})
        values = list(getattr(cmd_msg, field))
        sensible = (set(names) <= set(_AXES) and len(set(names)) == len(names) and len(values) == len(names)
                    and all(math.isfinite(v) for v in values))
        return MessageCase("joint_command_values", lambda: [plant.joint_command_values(cmd_msg, _AXES, field)],
                           [dict(zip(names, values, strict=True))] if sensible else None, f"{field} of {cmd_msg}")
    if kind < 3:
        msg = JointState(name=names, position=_values(rng, len(names)), velocity=_values(rng, len(names)))
        if kind == 0:
            return MessageCase("joint_position", lambda: (control.joint_position(msg, axis),),
                               _lookup(names, [msg.position], axis), f"{axis} of {msg}")
        velocity = list(msg.velocity) or [0.0] * len(names)  # no velocities: zeros, as documented
        if kind == 1:
            expected = _all_axes(names, [msg.position, velocity])
            return MessageCase("joint_positions", lambda: [list(v) for v in control.joint_positions(msg, _AXES)],
                               expected, str(msg))
        return MessageCase("joint_velocity", lambda: (control.joint_velocity(msg, axis),),
                           _lookup(names, [velocity], axis), f"{axis} of {msg}")
    if kind < 5:
        msg = Reference(axis_names=names, position_m=_values(rng, len(names)), velocity_m_s=_values(rng, len(names)),
                        acceleration_m_s2=_values(rng, len(names)))
        if kind == 3:
            arrays = [msg.position_m, msg.velocity_m_s, msg.acceleration_m_s2]
            return MessageCase("reference_axis", lambda: control.reference_axis(msg, axis),
                               _lookup(names, arrays, axis), f"{axis} of {msg}")
        expected = _all_axes(names, [msg.position_m])
        return MessageCase("reference_positions", lambda: [control.reference_positions(msg, _AXES)], expected,
                           str(msg))
    if kind == 5:
        comp = Compensation(axis_names=names, correction=_values(rng, len(names)))
        return MessageCase("compensation_for", lambda: (control.compensation_for(comp, axis),),
                           _lookup(names, [comp.correction], axis), f"{axis} of {comp}")
    if kind == 6:
        err = ContourError(axis_names=names, tracking_error_m=_values(rng, len(names)),
                           contour_error_m=rng.choice((0.1, *_BAD_FLOATS)), angle_rad=rng.choice((0.2, math.nan)))
        all_axes = _all_axes(names, [err.tracking_error_m])
        finite = math.isfinite(err.contour_error_m) and math.isfinite(err.angle_rad)
        expected = None if all_axes is None or not finite else (err.contour_error_m, err.angle_rad, all_axes[0])
        return MessageCase("contour_error_values", lambda: control.contour_error_values(err, _AXES), expected,
                           str(err))
    cmd = AxisCommand(axis_name=rng.choice(("x", "y", "", "xx")), command=rng.choice((0.5, -3.0, *_BAD_FLOATS)))
    expected = (cmd.command,) if cmd.axis_name == axis and math.isfinite(cmd.command) else None
    return MessageCase("command_value", lambda: (plant.command_value(cmd, axis),), expected,
                       f"{axis} of {cmd}")


def _same(got: Any, expected: Any) -> bool:
    return bool(np.array_equal(np.asarray(got, dtype=object), np.asarray(expected, dtype=object)))


def check_message(case: MessageCase) -> str | None:
    """Decode the message; the nonsense it was accepted with, if any."""
    try:
        got = case.call()
    except CncError:
        return None
    if case.expected is None:
        return (f"{case.name} accepted a message with a missing or repeated axis, a length mismatch or a "
                f"non-finite value: {case.message}")
    if not _same(tuple(got), tuple(case.expected)):
        return f"{case.name} returned {got!r}, the message holds {case.expected!r}"
    return ""


# =========================================================================== damaged bags
@dataclass(frozen=True)
class BagCase:
    """The damaged bytes of the small bag's ``.mcap`` file and what was done to them."""

    data: bytes
    damage: str


@dataclass
class _SmallBag:
    """A 200-tick circle bag written once per process, its joint states, and a folder to damage copies in."""

    data: bytes
    metadata: str
    stamps_ns: Any
    positions_m: Any
    work: Path


_SMALL: list[_SmallBag] = []


def small_bag() -> _SmallBag:
    """The small bag of this process (written on first use in a temporary folder removed at exit)."""
    if not _SMALL:
        import atexit
        import shutil
        import tempfile

        from cnc_tools.bagio.bag import read_bag
        from cnc_tools.bagio.synthetic import circle_program, circle_trajectory, write_run_bag

        root = Path(tempfile.mkdtemp(prefix="fuzz_bag_"))
        atexit.register(shutil.rmtree, root, True)
        bag = write_run_bag(root / "small", circle_program(), circle_trajectory(0.02, 5e-6, n=200))
        run = read_bag(bag)
        work = root / "damaged"
        work.mkdir()
        _SMALL.append(_SmallBag((bag / "small.mcap").read_bytes(), (bag / "metadata.yaml").read_text(),
                                run.joint_states.stamp_ns, run.joint_states.position_m, work))
    return _SMALL[0]


def bag_input(rng: random.Random) -> BagCase:
    """The small bag with bits flipped, bytes overwritten or inserted, or the file cut."""
    data = bytearray(small_bag().data)
    what = rng.randrange(4)
    at = rng.randrange(len(data))
    if what == 0:
        for _ in range(rng.randint(1, 3)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        return BagCase(bytes(data), "bits flipped")
    if what == 1:
        return BagCase(bytes(data[:at]), f"cut at byte {at}")
    if what == 2:
        return BagCase(bytes(data[:at] + bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 16))) + data[at:]),
                       f"bytes inserted at {at}")
    span = rng.randint(1, 64)
    data[at:at + span] = bytes(b ^ rng.randint(1, 255) for b in data[at:at + span])
    return BagCase(bytes(data), f"{span} bytes overwritten at {at}")


def check_bag(case: BagCase) -> str | None:
    """Read the damaged bag; the nonsense it was accepted with, if any."""
    from cnc_tools.bagio.bag import read_bag

    small = small_bag()
    folder = small.work / "small"
    folder.mkdir(exist_ok=True)
    (folder / "small.mcap").write_bytes(case.data)  # no metadata.yaml: the counts come from the file's summary
    try:
        run = read_bag(folder)
    except CncError:
        return None
    if run.integrity.complete:
        return f"bag with {case.damage} judged complete"
    stamps, positions = run.joint_states.stamp_ns, run.joint_states.position_m
    at = np.searchsorted(small.stamps_ns, stamps)
    known = (at < small.stamps_ns.size) & (small.stamps_ns[np.minimum(at, small.stamps_ns.size - 1)] == stamps)
    if not known.all() or not np.array_equal(positions, small.positions_m[at]):
        return f"bag with {case.damage} gave joint states the intact bag does not hold"
    return ""
