from glob import glob

from setuptools import find_packages, setup

PACKAGE = "cnc_plant_sim"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["py.typed"]},  # typed (PEP 561): mypy.ini checks it strict
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC contour-control developers",
    maintainer_email="cnc-contour@example.org",
    description="Plant simulation of CNC feed drives: axis models, friction, disturbances, the lockstep plant node.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "plant = cnc_plant_sim.nodes.plant_node:main",
        ],
    },
)
