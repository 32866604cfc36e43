"""ament_python package cnc_analysis: installs with colcon (ROS) or pip (plain venv)."""
from setuptools import find_packages, setup

PACKAGE = "cnc_analysis"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="CNC control team",
    maintainer_email="dev@cnc.local",
    description="The judge of recorded runs: rosbag2 recording and reading, drilling, thread and air-cut analysers, "
                "cycle time and following error, independent of the planner.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": [
        "cnc-identify = cnc_analysis.identify_cli:main",
    ]},
)
