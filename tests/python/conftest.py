# The Python module's tests (python/): run by ctest as python_tests (tests/CMakeLists.txt), which
# sets PYTHONPATH to the built module and names the build, source and shared-data folders. Run by
# hand: PYTHONPATH=build/python python3 -m pytest tests/python
import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("STREETLIGHT_BINARY_DIR", ROOT / "build"))
SHARED = pathlib.Path(os.environ.get("STREETLIGHT_SHARED_DATA", ROOT.parent / "shared" / "data"))
KITTI = SHARED / "street" / "kitti_000008"
TRUCK = SHARED / "models" / "CesiumMilkTruck.glb"
RELEASED = ROOT / "models" / "streetlight.safetensors"


@pytest.fixture(scope="session")
def kitti():
    """The shared KITTI frame and truck, or a skip that says what is missing."""
    for p in (KITTI / "000008.png", KITTI / "000008_velodyne.bin", KITTI / "000008_calib.json", TRUCK):
        if not p.exists():
            pytest.skip(f"shared data absent: {p} (the KITTI frame and truck live in ../shared/data)")
    return KITTI


@pytest.fixture(scope="session")
def released():
    if not RELEASED.exists():
        pytest.skip(f"released model absent: {RELEASED}")
    return str(RELEASED)


@pytest.fixture(scope="session")
def tool():
    def path(name):
        exe = BUILD / "tools" / name
        if not exe.exists():
            pytest.skip(f"{exe} is not built")
        return str(exe)
    return path
