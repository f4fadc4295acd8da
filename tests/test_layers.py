"""The declared layers hold: every arrow between the suite's sub-packages runs down, and top levels stay small.

The order is declared once, in ``docs/design.md``'s ``layers`` block, and read from there. An arrow is an
import anywhere in a module (at the top or inside a function) or a ``"package.module:name"`` string that a
lazy registry imports later. Within a package an arrow may go to the same sub-package or to a lower layer;
two sub-packages of one layer are independent. Across packages, arrows run down the ``packages`` line.
"""
from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DESIGN = ROOT / "docs" / "design.md"
PACKAGES_KEY = "packages"
MAX_TOP_LEVEL_MODULES = 8
LAZY_TARGET = re.compile(r"^(cnc_contour_control|cnc_plant_sim|cnc_tools)"
                         r"((?:\.[A-Za-z_][A-Za-z0-9_]*)+)(?::[A-Za-z_]\w*)?$")


def declared_layers() -> dict[str, list[set[str]]]:
    """``docs/design.md``'s layers block: package -> its layers, lowest first (each a set of names)."""
    block = re.search(r"```layers\n(.*?)```", DESIGN.read_text(), re.S)
    assert block, "docs/design.md has no ```layers block"
    layers: dict[str, list[set[str]]] = {}
    for line in block.group(1).strip().splitlines():
        package, _, order = line.partition(":")
        layers[package.strip()] = [{name.strip() for name in layer.split(",")} for layer in order.split("<")]
    return layers


def package_dir(package: str) -> Path:
    return ROOT / "src" / package / package


def modules(package: str) -> Iterator[tuple[str, Path]]:
    """(dotted name, path) of every module of ``package``."""
    base = package_dir(package)
    for path in sorted(base.rglob("*.py")):
        parts = path.relative_to(base.parent).with_suffix("").parts
        yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts), path


def arrows(path: Path) -> Iterator[tuple[str, int]]:
    """(imported dotted name, line) for every import and lazy ``module:name`` string in a file."""
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module, node.lineno
            for alias in node.names:
                yield f"{node.module}.{alias.name}", node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, node.lineno
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            match = LAZY_TARGET.match(node.value)
            if match:
                yield match.group(1) + match.group(2), node.lineno


def unit_of(dotted: str, layers: dict[str, list[set[str]]]) -> tuple[str, str] | None:
    """(package, sub-package or top-level module) of a suite module; None for anything else."""
    parts = dotted.split(".")
    if parts[0] not in layers or len(parts) < 2:
        return None
    return parts[0], parts[1]


def rank(layers: list[set[str]], name: str) -> int | None:
    return next((i for i, layer in enumerate(layers) if name in layer), None)


PACKAGES = ["cnc_contour_control", "cnc_plant_sim", "cnc_tools"]


def test_the_declaration_names_every_package_and_each_unit_once() -> None:
    layers = declared_layers()
    assert layers[PACKAGES_KEY] == [{p} for p in PACKAGES]
    for package in PACKAGES:
        names = [n for layer in layers[package] for n in layer]
        assert len(names) == len(set(names)), f"{package}: a name declared twice"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_unit_of_the_package_is_declared(package: str) -> None:
    layers = declared_layers()[package]
    units = {p.stem for p in package_dir(package).iterdir()
             if (p.is_dir() and (p / "__init__.py").exists()) or (p.suffix == ".py" and p.stem != "__init__")}
    undeclared = sorted(u for u in units if rank(layers, u) is None)
    assert not undeclared, f"{package}: declare these in docs/design.md's layers block: {undeclared}"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_arrow_runs_down(package: str) -> None:
    layers = declared_layers()
    order = [next(iter(layer)) for layer in layers[PACKAGES_KEY]]
    upward = []
    for module, path in modules(package):
        here = unit_of(module, layers)
        for target, line in arrows(path):
            there = unit_of(target, layers)
            if here is None or there is None or there == here:
                continue
            where = f"{path.relative_to(ROOT)}:{line} {module} -> {target}"
            if there[0] != here[0]:
                if order.index(there[0]) > order.index(here[0]):
                    upward.append(where)
                continue
            mine, theirs = rank(layers[package], here[1]), rank(layers[package], there[1])
            if theirs is None or mine is None or theirs >= mine:
                upward.append(where)
    assert not upward, "arrows that do not run down the declared layers:\n" + "\n".join(upward)


@pytest.mark.parametrize("package", PACKAGES)
def test_the_top_level_is_small(package: str) -> None:
    top = sorted(p.name for p in package_dir(package).glob("*.py"))
    assert len(top) <= MAX_TOP_LEVEL_MODULES, f"{package} has {len(top)} top-level modules: {top}"


def test_an_upward_import_is_caught(tmp_path: Path) -> None:
    """The checker itself: a core module importing a node, and a lazy string naming one, are both arrows."""
    source = tmp_path / "m.py"
    source.write_text("def f():\n    from cnc_contour_control.nodes import common\n"
                      "X = 'cnc_tools.cli.main:main'\n")
    found = {target for target, _ in arrows(source)}
    layers = declared_layers()
    assert unit_of("cnc_contour_control.nodes.common", layers) in {unit_of(t, layers) for t in found}
    assert ("cnc_tools", "cli") in {unit_of(t, layers) for t in found}
    control = layers["cnc_contour_control"]
    nodes, core = rank(control, "nodes"), rank(control, "core")
    assert nodes is not None and core is not None and nodes > core
