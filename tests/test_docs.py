"""The docs build with no broken link or missing page (``mkdocs build --strict``), every page shows
what it includes (no raw snippet marker: a formatter once turned one into text that mkdocs cannot
notice), and the tutorial's estimator does what the tutorial says it does (as navlie runs its
examples)."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bus import statistics
from bus.estimators import ESTIMATORS, EstimatorEntry
from bus.faults import BY_KIND
from examples import compass, derated_gnss, fog

ROOT = Path(__file__).resolve().parents[1]


def test_the_docs_build_strictly(tmp_path):
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    if mkdocs is None:
        pytest.fail("mkdocs is not installed: it is a dev dependency (pip install -e '.[dev]')")
    result = subprocess.run(
        [mkdocs, "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "swarm up" in cli and "--vehicles" in cli  # generated from the typer app
    config = (tmp_path / "site" / "reference" / "config" / "index.html").read_text()
    assert all(name in config for name in ESTIMATORS)  # generated from the registry and the models
    raw = [p for p in (tmp_path / "site").rglob("*.html") if re.search(r"--8\s*(&lt;|<)\s*--", p.read_text())]
    assert raw == [], f"pages showing a snippet marker instead of the file: {raw}"
    tutorial = (tmp_path / "site" / "tutorial" / "adding-an-estimator" / "index.html").read_text()
    for code in ("class DeratedGnss", "def from_config", "def compare"):  # the estimator and its runner, included
        assert code in re.sub(r"<[^>]+>", "", tutorial), code
    recipe = (tmp_path / "site" / "tutorial" / "adding-a-fault-kind" / "index.html").read_text()
    for code in ("class Fog(Zone)", "def silences", "def frames_in_fog"):  # the kind and its example, included
        assert code in re.sub(r"<[^>]+>", "", recipe), code
    recipe = (tmp_path / "site" / "tutorial" / "adding-an-experiment" / "index.html").read_text()
    for code in ("def plan(", "def measure(", "def conclude("):  # the experiment, included
        assert code in re.sub(r"<[^>]+>", "", recipe), code
    recipe = (tmp_path / "site" / "tutorial" / "adding-a-sensor" / "index.html").read_text()
    for code in ("class Compass(SensorKind)", "def measure(", "class CompassPart", "def compare("):
        assert code in re.sub(r"<[^>]+>", "", recipe), code
    faults = re.sub(r"<[^>]+>", "", (tmp_path / "site" / "faults" / "index.html").read_text())
    assert all(f"{kind}\n" in faults or f"{kind} " in faults for kind in BY_KIND)  # the table, from the registry


def test_the_tutorial_estimator_is_consistent_where_the_plain_ekf_is_not():
    runs = 10
    anees = derated_gnss.compare(range(1, runs + 1))
    low, high = statistics.chi2_band(3, runs=runs)
    assert low <= anees["ekf-derated"] <= high, anees
    assert anees["ekf"] > high, anees  # the control: the same worlds, the reports taken at their word


def test_one_registry_line_makes_the_tutorial_estimator_selectable(monkeypatch):
    from bus.config import build_config
    from vehicle.estimators import get_estimator

    line = "vehicle.estimators.derated_gnss"  # where the tutorial puts the module, the line it adds
    monkeypatch.setitem(ESTIMATORS, "ekf-derated", EstimatorEntry(line, "the tutorial's"))
    config = build_config({}).for_vehicle()
    config = config.model_copy(update={"vehicle": config.vehicle.model_copy(update={"estimator": "ekf-derated"})})
    assert get_estimator(config, 1).name == "ekf-derated"


def test_the_recipe_s_fault_kind_blinds_the_cameras_inside_its_zone_only():
    counts = fog.frames_in_fog()
    assert counts["fog, made inside the bank"] == 0  # nothing inside the bank
    assert 0 < counts["fog"] < counts["clear"]  # the frames outside it are still made


def test_a_fault_kind_is_one_module_and_one_registry_line():
    """Everything `swarm fault add`, chaos and the scene know of a kind comes from the registry: a kind
    the registry lists has its flags, and the scene draws its zone in its own colour."""
    from cli.fault_flags import flags
    from groundstation.scene_primitives import zone_colour

    assert "fog" in BY_KIND and {"center_m", "radius_m"} <= set(flags(["fog"]))
    assert zone_colour("fog") == BY_KIND["fog"].marker


def test_the_recipe_s_compass_bounds_the_heading_and_keeps_the_filter_consistent():
    runs = 10
    scores = compass.compare(range(1, runs + 1))
    low, high = statistics.chi2_band(3, runs=runs)
    assert low <= scores["compass"]["anees"] <= high, scores
    assert scores["compass"]["heading_rms_rad"] < scores["no compass"]["heading_rms_rad"] / 5, scores


def test_a_sensor_is_a_registry_line_away_from_every_process():
    """The registry's sensor is in the feed's layout, the datasheet, link-fault topics and blackouts,
    and a vehicle whose datasheet has it on gets its part in any estimator; one with it off does not."""
    from bus.config import build_config
    from bus.faults import LINK_TOPICS, Blackout
    from bus.feed import LAYOUT
    from bus.sensors import SENSORS
    from vehicle.estimators import get_estimator

    for sensor in SENSORS:
        assert sensor.topic in LAYOUT and sensor.topic in LINK_TOPICS
        Blackout(vehicle=1, sensor=sensor.topic)
        on = build_config({"sensors": {sensor.topic: {"rate_hz": 5}}}).for_vehicle()
        for estimator in ("ekf", "ukf"):
            config = on.model_copy(update={"vehicle": on.vehicle.model_copy(update={"estimator": estimator})})
            assert len(get_estimator(config, 1).parts) == 1
        assert get_estimator(build_config({}).for_vehicle(), 1).parts == []
