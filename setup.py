"""One distribution holding the numerical core (tcomp_core) and the ROS 2 nodes (tcomp_ros)."""

from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE_NAME = "tcomp_ros"

# ROS 2 Jazzy from pinned PyPI wheels, for machines without a sourced ROS install.
# Unpinned ros-rclpy resolves to a newer distribution, so every wheel is pinned.
ROS_WHEELS = [
    "ros-rclpy==7.1.6",
    "ros-sensor-msgs==5.3.6",
    "ros-diagnostic-msgs==5.3.6",
    "ros-std-msgs==5.3.6",
    "ros-rosgraph-msgs==2.0.3",  # /clock of the replay node
    "ros-rcl-interfaces==2.0.3",  # parameter descriptors
    "ros-rmw-fastrtps-cpp==8.4.3",
]

setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    description="Two-thermocouple lag compensation (Hung et al. 2005) for ROS 2",
    license="Apache-2.0",
    python_requires=">=3.11",
    packages=find_packages(include=["tcomp_core", "tcomp_core.*", "tcomp_ros", "tcomp_ros.*"]),
    package_data={"tcomp_core": ["py.typed"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE_NAME}"]),
        (f"share/{PACKAGE_NAME}", ["package.xml"]),
        (f"share/{PACKAGE_NAME}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE_NAME}/bags", ["bags/README.md"]),
        # The sample bags (tcomp_core.bundled finds them here once installed).
        *(
            (f"share/{PACKAGE_NAME}/{bag}", sorted(glob(f"{bag}/*")))
            for bag in sorted(glob("bags/*"))
            if Path(bag, "metadata.yaml").is_file()
        ),
    ],
    install_requires=[
        "numpy>=1.26",
        "scipy>=1.11",
        "rosbags>=0.10",
        "ruamel.yaml>=0.17",  # QoS profiles and metadata.yaml written (rosbags depends on it too)
        "PyYAML>=6.0",  # metadata.yaml read (libyaml's parser)
        "zstandard>=0.22",  # MCAP chunk compression (tcomp process reads and writes chunks)
        "lz4>=4.0",
        "matplotlib>=3.8",
        "tqdm>=4.60",  # progress bar of tcomp process
        "dask[distributed]>=2024.1",  # tcomp campaign: local or remote cluster
        "pyarrow>=15",  # tcomp campaign's table as Parquet
        "numba>=0.60",  # the radiating and level-dependent lag's loop in every free-run fit
    ],
    extras_require={
        "ros": ROS_WHEELS,
        "test": [
            "pytest>=8",
            "pytest-xdist>=3.5",  # make test runs the suite on every core
            "hypothesis>=6.100",  # property-based fuzzing of the readers, the CLI and the node
            "ruff>=0.5",
            "mypy>=2",
            "scipy-stubs>=1.17",
            "types-PyYAML>=6.0",  # the metadata reader's yaml, for mypy
            "mcap>=1.1",  # a third-party reader of the bags we write
            "pybag-sdk==0.13.0",
        ],
    },
    zip_safe=True,
    entry_points={
        "console_scripts": [
            "tcomp = tcomp_core.cli:main",
            "compensator_node = tcomp_ros.compensator:main",
            "replay_node = tcomp_ros.replay:main",
        ],
    },
)
