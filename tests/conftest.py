"""Hypothesis profiles: `default` (a few hundred examples per fuzz test, in `make test`) and
`fuzz-long` (10,000 examples, `make fuzz`). Pick one with --hypothesis-profile.

One BLAS thread per test process, as every swarm process has (launch/launcher.py): with two
pytest-xdist workers on two cores, OpenBLAS's threads in each spin against the other's (three
seeded ekf-slam runs took 39 s side by side, 8 s with one thread each).

The long files (integration, monte_carlo) are collected first: the suite's two workers take a file at
a time in collection order (`--no-loadscope-reorder`), so the long ones start early and the many
short ones fill in at the end instead of one worker finishing a long file alone.

Replays keep their calibrations (launch.calibration_cache) in a folder of this run's own, shared by
its workers: the suite neither reads nor fills the user's cache."""

import os

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("default", max_examples=300, deadline=None)
settings.register_profile("fuzz-long", max_examples=10_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("default")


def pytest_collection_modifyitems(items: list) -> None:
    def short(item) -> bool:
        return not (item.get_closest_marker("integration") or item.get_closest_marker("monte_carlo"))

    items.sort(key=short)  # stable: the order inside each group is kept


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


@pytest.fixture(scope="session", autouse=True)
def _calibrations_of_this_run(tmp_path_factory):
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # xdist: one base per worker
    with pytest.MonkeyPatch.context() as env:
        env.setenv("SWARMLOC_CACHE", str(shared / "swarmloc-cache"))  # the replays this suite starts inherit it
        yield
