"""The scenario file format's version, and the refusal of gains written for the format before it (ROS-free).

Format 2 states the servo laws' gains in time units (``ki`` [1/s], ``kd`` [s]), so another sample time keeps
the loop; format 1 gave them per sample. A format-1 file read as format 2 runs a different loop, often an
unstable one, so a file without ``format_version`` whose gains look per-sample is refused with the conversion,
and a file that names another version is refused outright.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from cnc_contour_control.axis.servo import ServoConfig
from cnc_contour_control.core.errors import ConfigError

#: The format this suite reads: gains in time units.
FORMAT_VERSION = 2
#: A derivative time at or above this [s] reads as a per-sample ``kd`` (paper 000's 6.7 per sample is 0.067 s at
#: T = 10 ms; no position loop here has a derivative time near a second).
PER_SAMPLE_KD_HINT_S = 0.5


def check_format(raw: Mapping[str, Any], servos: Sequence[ServoConfig], sample_time_s: float) -> None:
    """Refuse another ``format_version``, and, without one, gains that look per sample (naming the conversion)."""
    version = raw.get("format_version")
    if version is not None:
        if isinstance(version, bool) or version != FORMAT_VERSION:
            raise ConfigError(f"scenario.format_version must be {FORMAT_VERSION} (gains in time units), "
                              f"got {version!r}")
        return
    for servo in servos:
        kd = servo.law_params.get("kd")
        if isinstance(kd, (int, float)) and not isinstance(kd, bool) and kd >= PER_SAMPLE_KD_HINT_S:
            raise ConfigError(_per_sample_message(servo, float(kd), sample_time_s))


def _per_sample_message(servo: ServoConfig, kd: float, sample_time_s: float) -> str:
    ki = servo.law_params.get("ki")
    ki_text = "" if not isinstance(ki, (int, float)) else f"ki = {ki:g} / {sample_time_s:g} = {ki / sample_time_s:g}, "
    return (f"scenario has no format_version and servo {servo.axis_name}'s law_params.kd = {kd:g} looks like a "
            f"per-sample gain (a derivative time of {kd:g} s, >= {PER_SAMPLE_KD_HINT_S:g} s). Since format "
            f"{FORMAT_VERSION} the gains are in time units: ki [1/s] = ki per sample / T, kd [s] = kd per sample * T; "
            f"at T = {sample_time_s:g} s: {ki_text}kd = {kd:g} * {sample_time_s:g} = {kd * sample_time_s:g}. "
            f"Convert them and add 'format_version: {FORMAT_VERSION}' to the file (or add it alone if the gains are "
            f"meant as they are)")
