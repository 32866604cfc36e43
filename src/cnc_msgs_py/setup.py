"""ament_python package cnc_msgs_py: installs with colcon (ROS) or pip (plain venv)."""
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "cnc_msgs_py"
ROOT = Path(__file__).resolve().parents[2]  # the workspace: config/ lives there

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config/machines", glob(str(ROOT / "config/machines/*.yaml"))),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC control team",
    maintainer_email="dev@cnc.local",
    description="CNC job, status and cancel schemas, topic names, QoS profiles and machine descriptions shared by the planner, the bridge and cell controllers.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": []},
)
