"""``bench hops``: interleaved rounds of the bare hop, the relay and the node graph, judged on the median.

Tier 1 for the options and the summary; tier 2 for one real round (real
processes over loopback DDS) under two profiles.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import pytest

from cnc_contour_control.core.errors import ConfigError
from cnc_tools.bench import hops
from cnc_tools.bench.hops import (
    PROFILE_VARIABLES,
    SHIPPED,
    Plan,
    RoundFigures,
    dds_profile,
    hops_bench,
    measure_round,
    parse_profiles,
    summarize,
)
from cnc_tools.runs.dds import profile_path


def _round(profile: str, index: int, bare_us: float, relay_us: float, graph_us: float) -> RoundFigures:
    return RoundFigures(profile, index, bare_us * 1e-6, relay_us * 1e-6, graph_us * 1e-6, 1.0)


def test_the_goal_is_judged_on_the_median_of_the_rounds_ratios_per_profile() -> None:
    rounds = [_round("shipped", 1, 100, 150, 140), _round("shipped", 2, 200, 300, 400),
              _round("shipped", 3, 100, 160, 170), _round("udp", 1, 100, 150, 250)]
    rows = {row["profile"]: row for row in summarize(rounds)}
    shipped = rows["shipped"]
    assert shipped["rounds"] == 3
    assert shipped["graph_over_bare"] == {"median": pytest.approx(1.7), "min": pytest.approx(1.4),
                                          "max": pytest.approx(2.0)}
    assert shipped["relay_over_bare"]["median"] == pytest.approx(1.5)
    assert shipped["graph_over_relay"]["median"] == pytest.approx(170 / 160)
    assert not shipped["met"]  # 1.7 > 1.5, although round 1 alone met it
    assert rows["udp"]["graph_over_bare"]["median"] == pytest.approx(2.5) and not rows["udp"]["met"]
    assert summarize([_round("shipped", 1, 100, 120, 140)])[0]["met"]


def test_a_profile_option_must_name_an_existing_file_under_a_new_name(tmp_path: Path) -> None:
    other = tmp_path / "other.xml"
    other.write_text("<profiles/>")
    assert parse_profiles([f"other={other}"]) == {SHIPPED: profile_path(), "other": other}
    for bad, words in ((str(other), "NAME=PATH"), (f"shipped={other}", "taken"),
                       (f"x={tmp_path / 'missing.xml'}", "no file")):
        with pytest.raises(ConfigError, match=words):
            parse_profiles([bad])
    with pytest.raises(ConfigError, match="--rounds must be >= 1"):
        Plan(rounds=0)


def test_the_profile_applies_inside_the_block_only(tmp_path: Path) -> None:
    before = {name: os.environ.get(name) for name in PROFILE_VARIABLES}
    with dds_profile(tmp_path / "p.xml"):
        assert all(os.environ[name] == str(tmp_path / "p.xml") for name in PROFILE_VARIABLES)
    assert {name: os.environ.get(name) for name in PROFILE_VARIABLES} == before


#: A round small enough for a test: every side runs its real processes, each for a few ticks.
SMALL = Plan(rounds=1, round_trips=50, pingpong_warmup=10, relay_ticks=100, relay_warmup=10, graph_duration_s=0.1)


@pytest.mark.nodes
def test_one_round_measures_every_side_in_rotated_order(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    figures = measure_round(1, SHIPPED, profile_path(), tmp_path, SMALL)
    out = capsys.readouterr().out
    assert out.index("relay ...") < out.index("graph ...") < out.index("bare ...")  # round 2 starts at the relay
    assert 0.0 < figures.bare_hop_s < 0.1 and 0.0 < figures.relay_hop_s < 0.1 and 0.0 < figures.graph_hop_s < 0.1
    summary = json.loads((tmp_path / "round2_shipped_graph" / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["ticks"] == 101  # t = 0 .. 0.1 s


@pytest.mark.nodes
def test_the_bench_writes_each_round_under_each_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hops, "QUICK", SMALL)  # the rounds and the files are the point here, not the figures
    udp = tmp_path / "udp.xml"
    udp.write_text(profile_path().read_text())
    options = argparse.Namespace(quick=True, rounds=1, dds_profile=[f"copy={udp}"], out=tmp_path / "runs",
                                 json=tmp_path / "figures.json")
    assert hops_bench(options) == 0
    figures = json.loads((tmp_path / "figures.json").read_text())
    assert [(r["round"], r["profile"]) for r in figures["rounds"]] == [(1, SHIPPED), (1, "copy")]
    assert [row["profile"] for row in figures["summary"]] == [SHIPPED, "copy"]
    assert "median over the rounds" in capsys.readouterr().out
