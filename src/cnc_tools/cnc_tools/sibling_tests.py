"""Loading a test module beside another (ROS-free): pytest runs with ``--import-mode=importlib``, so test
files are not importable by name, and a test that reuses another file's cases or checks loads it by path."""
from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType


def sibling_module(test_file: str | Path, name: str) -> ModuleType:
    """The test module ``name`` (without ``.py``) in the folder of ``test_file`` (pass ``__file__``)."""
    path = Path(test_file).with_name(f"{name}.py")
    spec = importlib.util.spec_from_file_location(f"_{name}", path)
    if spec is None or spec.loader is None:
        raise ImportError(f"no test module {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
