"""``--against REV`` of the engine and graph benches: its default, its resolution, its refusal (no bench run).

Each test builds a small git repository of empty commits in ``tmp_path``.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from cnc_contour_control.core.errors import CncError
from cnc_tools.bench.engine import default_against, resolve_against
from cnc_tools.cli.main import build_parser


def git(repo: Path, *args: str) -> str:
    """Run git in ``repo`` with a fixed identity; its output, stripped."""
    command = ["git", "-C", str(repo), "-c", "user.name=bench", "-c", "user.email=bench@example.org", *args]
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout.strip()


def repo_of(tmp_path: Path, commits: int, tags: dict[str, int] | None = None) -> tuple[Path, list[str]]:
    """A repository of ``commits`` empty commits (hashes, oldest first), ``tags`` naming some of them by index."""
    git(tmp_path, "init", "-q")
    hashes = []
    for k in range(commits):
        git(tmp_path, "commit", "-q", "--allow-empty", "-m", f"commit {k}")
        hashes.append(git(tmp_path, "rev-parse", "HEAD"))
    for name, index in (tags or {}).items():
        git(tmp_path, "tag", name, hashes[index])
    return tmp_path, hashes


def test_without_tags_the_default_is_the_commit_before_head(tmp_path: Path) -> None:
    repo, hashes = repo_of(tmp_path, 3)
    assert default_against(repo) == "HEAD~1"
    assert resolve_against(None, repo) == (f"HEAD~1 = {hashes[1][:9]}", hashes[1])


def test_with_tags_the_default_is_the_previous_release_not_head_s_own_tag(tmp_path: Path) -> None:
    repo, hashes = repo_of(tmp_path, 4, {"v0.1": 0, "v0.2": 1, "v0.3": 3})
    assert default_against(repo) == "v0.2"
    assert resolve_against(None, repo) == (f"v0.2 = {hashes[1][:9]}", hashes[1])


def test_a_tag_a_branch_and_a_hash_resolve_to_their_commit(tmp_path: Path) -> None:
    repo, hashes = repo_of(tmp_path, 3, {"v1": 0})
    git(repo, "branch", "old", hashes[1])
    assert resolve_against("v1", repo)[1] == hashes[0]
    assert resolve_against("old", repo)[1] == hashes[1]
    assert resolve_against(hashes[2][:10], repo) == (hashes[2][:10], hashes[2])


@pytest.mark.parametrize("rev", ["no-such-rev", "HEAD~9", "--help"])
def test_a_rev_that_names_no_commit_is_refused_naming_the_option(tmp_path: Path, rev: str) -> None:
    repo, _ = repo_of(tmp_path, 2)
    with pytest.raises(CncError, match=f"--against {rev!r}|--against must name a tag, branch or commit, got {rev!r}"):
        resolve_against(rev, repo)


def test_a_single_commit_has_no_default_and_says_why(tmp_path: Path) -> None:
    repo, _ = repo_of(tmp_path, 1)
    with pytest.raises(CncError, match=r"--against 'HEAD~1' \(its default: no tag before HEAD.*names no commit"):
        resolve_against(None, repo)


def test_the_option_is_parsed_and_its_help_gives_the_default(capsys: pytest.CaptureFixture[str]) -> None:
    assert build_parser().parse_args(["bench", "engine"]).against is None
    assert build_parser().parse_args(["bench", "engine", "--against", "v1.0"]).against == "v1.0"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["bench", "--help"])
    assert "previous release tag" in " ".join(capsys.readouterr().out.split())
