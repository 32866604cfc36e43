"""ament_python package cnc_servo_bridge: installs with colcon (ROS) or pip (plain venv)."""
import os
from glob import glob
from pathlib import Path

from setuptools import Extension, find_packages, setup

PACKAGE = "cnc_servo_bridge"
HERE = Path(__file__).resolve().parent


def config(pattern: str) -> list[str]:
    """Files of the workspace's config/ (shared by the packages), relative to this package."""
    return sorted(os.path.relpath(f, HERE) for f in glob(str(HERE.parents[1] / "config" / pattern)))

# The drive model's kernel, compiled here (pip or colcon) so that no JIT compiler is loaded
# at run time. -ffp-contract=off keeps every multiply and add separately rounded, as numpy's
# are, so the kernel equals DriveModel.step (a fused multiply-add would differ in the last bit).
DRIVE_KERNEL = Extension(f"{PACKAGE}._drive_kernel", sources=[f"{PACKAGE}/_drive_kernel.c"],
                         extra_compile_args=["-O2", "-ffp-contract=off"])

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    ext_modules=[DRIVE_KERNEL],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", config("bridge.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="CNC control team",
    maintainer_email="dev@cnc.local",
    description="Servo drive emulation (position loop, feed-forward, velocity lag, limits) publishing joint_states.",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={"console_scripts": [
        "bridge = cnc_servo_bridge.bridge_main:main",
        "cnc-bridge = cnc_servo_bridge.bridge_main:main",
    ]},
)
