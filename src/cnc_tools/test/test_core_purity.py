"""Every core module imports without rclpy or message types (the ROS-free core)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2]
#: Modules that may talk to ROS: nodes, test helpers, the command line with its benchmarks, and a package's
#: own `ros` module (the live view's node: live/ros.py).
ROS_SIDE = ("nodes", "testing", "bench", "cli", "commands", "ros")


def core_modules() -> list[str]:
    names = []
    for package in ("cnc_contour_control", "cnc_plant_sim", "cnc_tools"):
        root = SRC / package / package
        for path in sorted(root.rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if any(part in ROS_SIDE for part in parts) or "__main__" in parts:
                continue
            module = ".".join((package, *parts)).removesuffix(".__init__")
            names.append(module)
    return names


def test_core_modules_never_import_rclpy() -> None:
    modules = core_modules()
    assert len(modules) > 20
    script = "import importlib, sys\n" + "".join(f"importlib.import_module({m!r})\n" for m in modules) + (
        "bad = sorted(m for m in sys.modules\n"
        "             if m.split('.')[0] == 'rclpy' or (m.endswith('.msg') and not m.startswith('rosbags.')))\n"
        "print(bad)\nsys.exit(1 if bad else 0)\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
