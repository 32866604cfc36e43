"""ament_python package cnc_planner: installs with colcon (ROS) or pip (plain venv)."""
import os
from glob import glob
from pathlib import Path

from setuptools import Extension, find_packages, setup

PACKAGE = "cnc_planner"
HERE = Path(__file__).resolve().parent


def config(pattern: str) -> list[str]:
    """Files of the workspace's config/ (shared by the packages), relative to this package."""
    return sorted(os.path.relpath(f, HERE) for f in glob(str(HERE.parents[1] / "config" / pattern)))

# Bulk sampling of ruckig pieces (motion/_sample_kernel.c), the drill's lag margins
# (kinds/drill/_lag_kernel.c), the thread's stock check (kinds/thread/_stock_kernel.c) and
# its helix (kinds/thread/_helix_kernel.c), compiled here (pip or colcon);
# -ffp-contract=off keeps every multiply and add separately rounded, as numpy's are, so it
# equals the numpy evaluation (a fused multiply-add would differ in the last bit).
KERNELS = [Extension(f"{PACKAGE}.{name.replace('/', '.')}", sources=[f"{PACKAGE}/{name}.c"],
                     depends=[f"{PACKAGE}/kernel_buffers.h", f"{PACKAGE}/ruckig_piece.h"],
                     extra_compile_args=["-O2", "-ffp-contract=off"])
           for name in ("motion/_sample_kernel", "kinds/drill/_lag_kernel", "kinds/thread/_stock_kernel",
                        "kinds/thread/_helix_kernel")]

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    ext_modules=KERNELS,
    package_data={PACKAGE: ["templates/*.j2"]},  # report.html's template, read by jinja2 from the package
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", config("planner.yaml")),
        (f"share/{PACKAGE}/config/jobs", config("jobs/*.yaml")),
    ],
    install_requires=["setuptools", "Jinja2>=3.1"],
    zip_safe=False,
    maintainer="CNC control team",
    maintainer_email="dev@cnc.local",
    description="Plans CNC jobs (drilling, turning, vibration, threads) into jerk-limited joint setpoints streamed as trajectory_msgs/JointTrajectory; run, plan and analyse CLIs.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": [
        "planner = cnc_planner.planner_main:main",
        "cnc-planner = cnc_planner.planner_main:main",
        "cnc-run = cnc_planner.cli:run_main",
        "cnc-plan = cnc_planner.cli:plan_main",
        "cnc-analyze = cnc_planner.cli:analyze_main",
        "cnc-cell = cnc_planner.cli:cell_main",
    ]},
)
