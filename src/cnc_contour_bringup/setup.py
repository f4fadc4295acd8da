from glob import glob

from setuptools import setup

PACKAGE = "cnc_contour_bringup"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=[],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC contour-control developers",
    maintainer_email="cnc-contour@example.org",
    description="Launch of a whole contour-control graph from one installed parameters file.",
    license="Apache-2.0",
)
