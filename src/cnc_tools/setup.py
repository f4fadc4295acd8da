from glob import glob

from setuptools import find_packages, setup

PACKAGE = "cnc_tools"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["py.typed", "live/layout.json"]},  # typed (PEP 561): mypy.ini checks it strict
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
        (f"share/{PACKAGE}/config", glob("config/*.xml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC contour-control developers",
    maintainer_email="cnc-contour@example.org",
    description="Scenarios, in-process engine, runner, recorder, bag I/O, scoring, reports, tuning and the "
                "cnc-contour command.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "cnc-contour = cnc_tools.cli.main:main",
            "recorder = cnc_tools.nodes.recorder_node:main",
            "composed = cnc_tools.nodes.composed_host:main",
            "replay = cnc_tools.nodes.replay_node:main",
            "lifecycle_manager = cnc_tools.nodes.lifecycle_manager:main",
            "live = cnc_tools.live.ros:main",
        ],
    },
)
