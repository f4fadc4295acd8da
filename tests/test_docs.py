"""The docs name only what exists: every repository path and every test name in ``docs/*.md`` and ``README.md``.

A *path* is a token of a doc (in backticks or in plain text) that contains a ``/`` and either ends in one of
``PATH_SUFFIXES`` or starts with one of the repository's top folders (``src/``, ``tests/``, ``scenarios/`` ...).
Tokens with a placeholder (``<axis>``, ``{``, ``$``, ``NNN``), absolute paths, ``../`` paths (outside the
repository) and URLs are not paths of the repository and are skipped. A path is found when
one of these exists (``resolve_path``), tried in order:

1. the repository root: ``tests/e2e/test_graph.py``, ``scenarios/paper000_circle_high.yaml``;
2. a package folder, ``src/<package>/``: ``config/fastdds_localhost.xml``, ``msg/Reference.msg``;
3. a package's Python package, ``src/<package>/<package>/``: ``axis/servo.py``, ``laws/registry.py``;
4. a path that starts with a package name, inside ``src/``: ``cnc_contour_control/axis/servo.py`` (its Python
   package) or ``cnc_contour_bringup/launch/contour_graph.launch.py`` (its package folder);
5. an installed data file, ``share/<package>/<rest>``, as ``src/<package>/<rest>``;
6. a scenario's own file, named relative to ``scenarios/`` as in a scenario: ``programs/helix_pocket.ngc``.

A ``*`` in a path is a glob: some file must match it under one of the same roots. A bare Python file name in
backticks (such as plan_stream.py) must be the name of some ``.py`` file under ``src/``, ``tests/`` or
``scripts/``, so a module that vanished is caught (run outputs such as summary.json are not checked).

A *dotted name* ``cnc_tools.runs.graph.run_graph`` (one of the three Python packages, then dots) is found when
its longest prefix that is a module or package of ``src/<package>/`` exists and the next part, if any, is a
word of that module's text (an attribute it defines or imports).

A *test name* is ``test_<word>`` not followed by ``.`` or ``/`` (optionally ``path::test_<word>``). It is found
when some test file defines ``def test_<word>`` (a test module's stem, ``test_engine`` for ``test_engine.py``,
counts too: the docs name test modules that way). A bare test file name ``test_<word>.py`` must exist in a test
folder.
"""
from __future__ import annotations

import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
PACKAGES = ("cnc_contour_control", "cnc_plant_sim", "cnc_tools", "cnc_contour_interfaces", "cnc_contour_bringup")
TOP_FOLDERS = ("src/", "tests/", "scenarios/", "docs/", "scripts/", "requirements/")
PATH_SUFFIXES = (".py", ".yaml", ".md", ".xml", ".msg", ".action", ".ngc", ".json")
TEST_DIRS = ("tests", *(f"src/{package}/test" for package in PACKAGES))
MAX_DESIGN_LINES = 600

TOKEN = re.compile(r"[\w.\-/:<>*{}$]+")
TEST_NAME = re.compile(r"(?<![\w/.])(test_\w+)(?![\w./])")
TEST_FILE = re.compile(r"(?<![\w/.])(test_\w+\.py)\b")
PLACEHOLDER = re.compile(r"[<>{}$]|(^|/)N+(/|\.|$)|paper00N")
DOTTED = re.compile(r"\b((?:cnc_contour_control|cnc_plant_sim|cnc_tools)(?:\.\w+)+)")
BARE_MODULE = re.compile(r"`([\w.\-]+\.py)`")


def candidate_paths(text: str) -> set[str]:
    """Every token of ``text`` that names a repository path (rules in the module docstring)."""
    found = set()
    for raw in TOKEN.findall(text):
        token = raw.split("::")[0].rstrip(".,:;)")
        if "/" not in token or token.startswith(("/", "../", "./", "http", "//")) or PLACEHOLDER.search(token):
            continue
        if token.endswith(PATH_SUFFIXES) or token.startswith(TOP_FOLDERS):
            found.add(token)
    return found


def resolve_path(token: str, root: Path = ROOT) -> Path | None:
    """The existing file or folder ``token`` names, by the rules of the module docstring; None if none."""
    tries = [root / token, root / "scenarios" / token]
    for package in PACKAGES:
        tries += [root / "src" / package / token, root / "src" / package / package / token]
        if token.startswith(f"{package}/"):
            rest = token[len(package) + 1:]
            tries += [root / "src" / package / package / rest, root / "src" / package / rest]
        if token.startswith(f"share/{package}/"):
            tries.append(root / "src" / package / token[len(f"share/{package}/"):])
    if "*" in token:
        return next((match for path in tries for match in sorted(path.parent.glob(path.name))), None)
    return next((path for path in tries if path.exists()), None)


def resolve_dotted(name: str, root: Path = ROOT) -> Path | None:
    """The module file a dotted name lives in (rules in the module docstring); None if it names nothing."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        base = root / "src" / parts[0] / Path(*parts[:end])
        module = next((f for f in (base.with_suffix(".py"), base / "__init__.py") if f.is_file()), None)
        if module is not None:
            rest = parts[end:]
            return module if not rest or re.search(rf"\b{re.escape(rest[0])}\b", module.read_text()) else None
    return None


@cache
def repository_file_names() -> frozenset[str]:
    """The names (no folder) of every file under ``src/``, ``tests/`` and ``scripts/``."""
    return frozenset(path.name for folder in ("src", "tests", "scripts") for path in (ROOT / folder).rglob("*.py"))


@cache
def defined_tests() -> frozenset[str]:
    """Names of every ``def test_...`` in the test folders, and the stems of the test modules."""
    names = set()
    for folder in TEST_DIRS:
        for path in (ROOT / folder).rglob("test_*.py"):
            names.add(path.stem)
            names.update(re.findall(r"def (test_\w+)", path.read_text()))
    return frozenset(names)


@cache
def named_test_files() -> frozenset[str]:
    return frozenset(path.name for folder in TEST_DIRS for path in (ROOT / folder).rglob("test_*.py"))


def doc_id(path: Path) -> str:
    return str(path.relative_to(ROOT))


@pytest.mark.parametrize("doc", DOCS, ids=doc_id)
def test_every_path_a_doc_names_exists(doc: Path) -> None:
    missing = sorted(token for token in candidate_paths(doc.read_text()) if resolve_path(token) is None)
    missing += sorted(set(BARE_MODULE.findall(doc.read_text())) - repository_file_names())
    assert not missing, f"{doc_id(doc)} names paths that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOCS, ids=doc_id)
def test_every_dotted_module_name_a_doc_names_exists(doc: Path) -> None:
    missing = sorted(name for name in set(DOTTED.findall(doc.read_text())) if resolve_dotted(name) is None)
    assert not missing, f"{doc_id(doc)} names modules or attributes that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOCS, ids=doc_id)
def test_every_test_a_doc_names_exists(doc: Path) -> None:
    text = doc.read_text()
    missing = sorted(set(TEST_NAME.findall(text)) - defined_tests())
    missing += sorted(set(TEST_FILE.findall(text)) - named_test_files())
    assert not missing, f"{doc_id(doc)} names tests that do not exist: {missing}"


def test_resolver_finds_real_paths_and_refuses_a_made_up_one() -> None:
    assert resolve_path("cnc_contour_control/axis/servo.py") is not None
    assert resolve_path("laws/registry.py") is not None
    assert resolve_path("config/fastdds_localhost.xml") is not None
    assert resolve_path("share/cnc_contour_control/config") is not None
    assert resolve_path("programs/helix_pocket.ngc") is not None
    assert resolve_path("cnc_contour_control/servo_that_never_was.py") is None
    assert resolve_path("bench/paper000_data.py") is None
    assert resolve_path("reproductions/paper000/*.py") is not None
    assert resolve_path("bench/paper000*.py") is None
    assert "paper000_data.py" not in repository_file_names()
    text = "see `src/cnc_tools/cnc_tools/bench/made_up.py` and docs/nowhere.md, not `servo/<axis>/command`"
    assert candidate_paths(text) == {"src/cnc_tools/cnc_tools/bench/made_up.py", "docs/nowhere.md"}
    assert all(resolve_path(token) is None for token in candidate_paths(text))


def test_dotted_names_resolve_to_modules_and_their_attributes() -> None:
    assert resolve_dotted("cnc_tools.runs.graph.run_graph") is not None
    assert resolve_dotted("cnc_contour_control.axis.servo") is not None
    assert resolve_dotted("cnc_tools.runner.run_graph") is None
    assert resolve_dotted("cnc_tools.runs.graph.run_graph_that_never_was") is None


def test_test_name_pattern_takes_names_not_files() -> None:
    text = "`test_engine` and tests/e2e/test_graph.py::test_lockstep_graph_matches_engine_to_1e9, test_x.py"
    assert set(TEST_NAME.findall(text)) == {"test_engine", "test_lockstep_graph_matches_engine_to_1e9"}
    assert "test_made_up_for_the_check" not in defined_tests()


def test_design_is_at_most_600_lines() -> None:
    lines = len((ROOT / "docs" / "design.md").read_text().splitlines())
    assert lines <= MAX_DESIGN_LINES, f"docs/design.md has {lines} lines, the bound is {MAX_DESIGN_LINES}"


@pytest.mark.parametrize("name", ["benchmarks.md", "reproduction.md"])
def test_doc_opens_with_a_table(name: str) -> None:
    """The first table comes before the first ``## `` section after the title."""
    lines = (ROOT / "docs" / name).read_text().splitlines()
    first_section = next((i for i, line in enumerate(lines) if line.startswith("## ")), len(lines))
    first_table = next((i for i, line in enumerate(lines) if line.startswith("|")), len(lines))
    assert first_table < first_section, (f"docs/{name}: first table at line {first_table + 1}, "
                                         f"first section at {first_section + 1}")
