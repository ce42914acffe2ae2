"""ament_python package: the ROS glue every node of the project shares."""
from setuptools import find_packages, setup

PACKAGE = "dva_ros_common"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    # aero-dva: the ROS-free domain package (aero_dva/), installed by scripts/setup.sh
    install_requires=["setuptools", "aero-dva"],
    zip_safe=True,
    maintainer="aero-dva maintainers",
    maintainer_email="maintainers@aero-dva.org",
    description="Executor, node main(), parameters, diagnostics and message conversions "
                "shared by the aero-dva nodes.",
    license="Apache-2.0",
)
