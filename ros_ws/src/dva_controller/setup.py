"""ament_python package: spectrum analysis and damper controllers for the tunable Maxwell DVA."""
from glob import glob

from setuptools import find_packages, setup

# The controller table (aero_dva, installed before the workspace is built) names the project's
# laws: the block-rate laws' executables are aliases of the generic controller node, the
# per-sample laws' of their supervisor node.
from aero_dva.control.controllers import BLOCK, SAMPLE, controllers

PACKAGE = "dva_controller"
ALIASES = [f"{entry.node} = dva_controller.controller_spec:main"
           for entry in controllers((BLOCK,), builtin_only=True)]
SUPERVISORS = [f"{entry.node} = dva_controller.switching_controller_spec:main"
               for entry in controllers((SAMPLE,), builtin_only=True)]

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
    ],
    # aero-dva: the ROS-free domain package (aero_dva/), installed by scripts/setup.sh
    install_requires=["setuptools", "aero-dva"],
    zip_safe=True,
    maintainer="aero-dva maintainers",
    maintainer_email="maintainers@aero-dva.org",
    description="Spectrum analysis and semi-active damper controllers for a Maxwell DVA.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "controller = dva_controller.controller_spec:main",
            *ALIASES,
            "spectrum = dva_controller.spectrum_spec:main",
            *SUPERVISORS,
        ],
    },
)
