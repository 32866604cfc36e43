"""ament_python package cnc_msgs_py: installs with colcon (ROS) or pip (plain venv)."""
import os
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "cnc_msgs_py"
HERE = Path(__file__).resolve().parent


def config(pattern: str) -> list[str]:
    """Files of the workspace's config/ (shared by the packages), relative to this package."""
    return sorted(os.path.relpath(f, HERE) for f in glob(str(HERE.parents[1] / "config" / pattern)))

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: ["*.xml"]},  # fastdds_local.xml
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config/machines", config("machines/*.yaml") + config("machines/*.tbl")),
        (f"share/{PACKAGE}/config", config("work_offsets.yaml")),
    ],
    install_requires=["setuptools", "tqdm>=4.66", "rosbags>=0.11"],
    zip_safe=True,
    maintainer="CNC control team",
    maintainer_email="dev@cnc.local",
    description="CNC job, status and cancel schemas, topic names, QoS profiles and machine descriptions shared by the planner, the bridge and cell controllers.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": [
        "cnc-submit = cnc_msgs_py.submit:main",
        "cnc-discovery-server = cnc_msgs_py.discovery_server:main",
    ]},
)
