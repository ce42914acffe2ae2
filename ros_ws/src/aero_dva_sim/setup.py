"""ament_python package: wing/DVA model (pure numerics) and the simulator and recorder nodes."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "aero_dva_sim"

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
    description="Simulator, recorder, bag player and run_flight nodes of the wing with a tunable "
                "Maxwell DVA.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "bag_player = aero_dva_sim.bag_player_spec:main",
            "mcap_recorder = aero_dva_sim.mcap_recorder_spec:main",
            "simulator = aero_dva_sim.simulator_spec:main",
            "run_flight = aero_dva_sim.run_flight:main",
            "replay_flight = aero_dva_sim.replay_flight:main",
        ],
    },
)
