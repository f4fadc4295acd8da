from glob import glob

from setuptools import find_packages, setup

PACKAGE = "cnc_contour_control"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["py.typed"]},  # typed (PEP 561): mypy.ini checks it strict
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),  # generated: cnc-contour config-files
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC contour-control developers",
    maintainer_email="cnc-contour@example.org",
    description="Contour control of a multi-axis CNC: interpolation, per-axis servo laws, contour-error estimation, "
                "compensation (ROS-free core and thin nodes).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "interpolator = cnc_contour_control.nodes.interpolator_node:main",
            "servo = cnc_contour_control.nodes.servo_node:main",
            "estimator = cnc_contour_control.nodes.estimator_node:main",
            "compensator = cnc_contour_control.nodes.compensator_node:main",
            "force_regulator = cnc_contour_control.nodes.force_regulator_node:main",
        ],
    },
)
