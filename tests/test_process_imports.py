"""Each process imports what its role needs (start-up time and memory scale with the swarm): a
vehicle without a camera, and a world without cameras, load no OpenCV and no scipy; nothing outside
the ground station loads the Foxglove SDK, and nothing loads matplotlib (the report is drawn after
the run, by the command that started it); a camera vehicle does load OpenCV (the control: the probe
sees what a process loads). Each role is started in a fresh interpreter as its process would be, up
to its loop (bench/startup.py)."""

import pytest

from bench.startup import probe

FORBIDDEN = {
    "vehicle": {"cv2", "scipy", "matplotlib", "foxglove", "rich"},
    "vehicle with a camera": {"matplotlib", "foxglove", "rich"},
    "world": {"cv2", "scipy", "matplotlib", "foxglove", "rich"},  # a world without cameras
    "ground station": {"matplotlib", "cv2", "scipy"},  # its live display is rich's; run.mcap is foxglove's
}


@pytest.mark.parametrize("role", list(FORBIDDEN))
def test_a_process_loads_only_what_its_role_needs(role):
    loaded = set(probe(role).modules)
    assert not loaded & FORBIDDEN[role], f"{role} loads {sorted(loaded & FORBIDDEN[role])}"
    assert {"zenoh", "pydantic"} <= loaded  # the probe is a process start: the bus and the config
    if role == "vehicle with a camera":
        assert "cv2" in loaded
    if role == "ground station":
        assert "foxglove" in loaded  # run.mcap
