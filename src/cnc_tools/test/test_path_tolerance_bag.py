"""The path tolerance travels in the bag's ``Path`` message: written, read back, scored beside the deviation.

A bag recorded before ``Path`` had ``path_tolerance_m`` (its own schema lacks the field) still reads and
scores, and says the tolerance is not recorded.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from cnc_contour_control.core.errors import BagError
from cnc_tools.analysis.scoring import score_run
from cnc_tools.bagio.bag import BagWriter, read_bag
from cnc_tools.bagio.typestore import custom_type_definitions, find_msg_dir, project_typestore

PATH_TYPE = "cnc_contour_interfaces/msg/Path"
FIELD_LINE = "float64 path_tolerance_m"


def _field_names(store: Typestore, type_name: str) -> list[str]:
    return [name for name, _ in store.fielddefs[type_name][1]]


def _store_before_the_field() -> Typestore:
    """Jazzy and the project's types, with ``Path`` as it was before ``path_tolerance_m``."""
    lines = (find_msg_dir() / "Path.msg").read_text(encoding="utf-8").splitlines()
    old_text = "\n".join(line for line in lines if not line.startswith(FIELD_LINE))
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register({**custom_type_definitions(find_msg_dir()), **get_types_from_msg(old_text, PATH_TYPE)})
    return store


def _circle_bag(tmp_path: Path, synth, tolerance_m: float | None, typestore: Typestore | None = None) -> Path:
    program = dataclasses.replace(synth.circle_program(), path_tolerance_m=tolerance_m)
    traj = synth.circle_trajectory(0.02, 3e-6, n=200)
    return synth.write_run_bag(tmp_path / "bag", program, traj, commands=False, typestore=typestore)


def test_the_message_declares_the_field() -> None:
    assert "path_tolerance_m" in _field_names(project_typestore(), PATH_TYPE)


@pytest.mark.parametrize("tolerance_m, text", [(1e-5, "path tolerance 10 µm"), (0.0, "path tolerance 0 (exact stop)"),
                                               (None, "path tolerance not recorded")])
def test_the_tolerance_is_read_back_and_scored_beside_the_deviation(tmp_path: Path, synth, tolerance_m: float | None,
                                                                    text: str) -> None:
    run = read_bag(_circle_bag(tmp_path, synth, tolerance_m))
    assert run.program.path_tolerance_m == tolerance_m  # None travels as NaN and comes back as None
    score = score_run(run)
    assert score.deviation is not None and score.deviation.tolerance_m == tolerance_m
    assert text in score.to_table()


def test_a_bag_recorded_before_the_field_reads_scores_and_says_not_recorded(tmp_path: Path, synth) -> None:
    old_store = _store_before_the_field()
    assert "path_tolerance_m" not in _field_names(old_store, PATH_TYPE)
    old = read_bag(_circle_bag(tmp_path / "old", synth, 1e-5, old_store))  # the writer's schema drops the value
    new = read_bag(_circle_bag(tmp_path / "new", synth, 1e-5))
    assert old.integrity.complete and old.program.path_tolerance_m is None
    assert len(old.program.segments) == len(new.program.segments) == 1
    score, new_score = score_run(old), score_run(new)
    assert score.deviation is not None and score.deviation.tolerance_m is None
    assert "path tolerance not recorded" in score.to_table()
    assert score.deviation.max_m == new_score.deviation.max_m  # the same reference, measured alike
    assert score.contour.values_si == new_score.contour.values_si


@pytest.mark.parametrize("bad_m", [-1e-6, math.inf])
def test_a_recorded_tolerance_below_zero_or_infinite_is_a_bag_error(tmp_path: Path, synth, bad_m: float) -> None:
    program = synth.circle_program()
    topics = {k: v for k, v in synth.TOPICS.items() if k != "/clock"}
    with BagWriter(tmp_path / "bad", topics) as writer:
        writer.write_message("/cnc/path", 0, dataclasses.replace(synth.path_message(program), path_tolerance_m=bad_m))
        writer.write_message("/cnc/joint_states", 1, synth.joint_state(1, ["x", "y"], np.zeros(2), np.zeros(2)))
        writer.write_message("/cnc/reference", 1, synth.reference(1, ["x", "y"], np.zeros(2), np.zeros(2)))
    with pytest.raises(BagError, match=rf"/cnc/path: the recorded program is invalid: path_tolerance_m must be "
                                       rf"finite and >= 0, got {bad_m}"):
        read_bag(tmp_path / "bad")
