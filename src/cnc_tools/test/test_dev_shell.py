"""``./dev shell`` puts every node executable on PATH and says which ROS domain and DDS profile it uses.

``./dev env`` prints what ``./dev shell`` prints before its prompt (the same
function of ``scripts/setup.sh``); it runs here non-interactively. Every
console script the packages declare (their ``setup.py`` entry points) must
resolve on PATH to the executable colcon installed for it,
``install/<package>/lib/<package>/<name>`` (what ``ros2 run`` starts).
"""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
SCRIPT = re.compile(r'"([\w-]+) = [\w.]+:\w+"')
REPORTED = re.compile(r"^executable (\S+) -> (.+)$", re.MULTILINE)


def console_scripts() -> dict[str, str]:
    """Executable name -> package, from every package's setup.py ``console_scripts``."""
    scripts = {}
    for setup in sorted(ROOT.glob("src/*/setup.py")):
        for name in SCRIPT.findall(setup.read_text()):
            scripts[name] = setup.parent.name
    return scripts


def dev_env(**env: str) -> str:
    """``./dev env``'s output in a shell without a domain or the workspace's executables on PATH."""
    base = {k: v for k, v in os.environ.items() if k not in ("ROS_DOMAIN_ID", "PYTEST_XDIST_WORKER")}
    base["PATH"] = os.pathsep.join(p for p in base["PATH"].split(os.pathsep) if not p.startswith(str(ROOT / "install")))
    result = subprocess.run([str(ROOT / "dev"), "env"], env={**base, **env}, capture_output=True, text=True,
                            timeout=600, check=False)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_the_packages_declare_the_nodes_and_tools() -> None:
    scripts = console_scripts()
    assert {"plant", "interpolator", "servo", "estimator", "compensator", "force_regulator", "recorder",
            "cnc-contour"} <= set(scripts)
    assert scripts["plant"] == "cnc_plant_sim" and scripts["servo"] == "cnc_contour_control"


def test_every_console_script_resolves_on_path_to_its_installed_executable() -> None:
    reported = dict(REPORTED.findall(dev_env(ROS_DOMAIN_ID="77")))
    for name, package in console_scripts().items():
        assert reported.get(name) == str(ROOT / "install" / package / "lib" / package / name), name
        assert os.access(reported[name], os.X_OK), name


def test_it_says_which_domain_and_dds_profile_it_uses() -> None:
    out = dev_env(ROS_DOMAIN_ID="77")
    assert re.search(r"^ROS_DOMAIN_ID=77 .*ROS_DOMAIN_ID=77 \./dev shell", out, re.MULTILINE), out
    profile = re.search(r"^FASTRTPS_DEFAULT_PROFILES_FILE=(.+)$", out, re.MULTILINE)
    assert profile is not None and Path(profile.group(1)).is_file(), out
    assert re.search(r"^ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST$", out, re.MULTILINE), out
    config = re.search(r"^CNC_CONFIG_DIR=(.+)$", out, re.MULTILINE)
    assert config is not None and (Path(config.group(1)) / "paper000_circle_high.params.yaml").is_file(), out


@pytest.mark.parametrize("draw", range(2))
def test_without_a_domain_each_shell_draws_one_in_1_to_100(draw: int) -> None:
    domain = re.search(r"^ROS_DOMAIN_ID=(\d+) ", dev_env(), re.MULTILINE)
    assert domain is not None and 1 <= int(domain.group(1)) <= 100
