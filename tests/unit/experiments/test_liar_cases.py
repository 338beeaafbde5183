"""The liar experiment's cases: the spoofer of the ``spoofed`` profile spoofs the liar and nobody
else, and the oracle rows cut the liar's V2V at the delay asked for; the summary scores what the
runs wrote."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.main import app
from experiments.liar import (
    DURATION_S,
    JAMMING_ENDS_AFTER_S,
    LIAR,
    LIE_START_S,
    Case,
    cases,
    liar_config,
    rangers_of_liar,
    summarize,
)
from sim.world import World


def test_the_spoofed_profile_spoofs_the_liar_and_nobody_else():
    """Every vehicle whose fixes the world ever moved by the spoofer (a zone centred on the liar's pad:
    a zone too wide captures neighbours passing by, as a 60 m one did)."""
    world = World(liar_config(Case("spoofed", True, seed=1)))
    spoofed: dict[int, float] = {}
    offset_of = world.faults.spoof_offset_m

    def recording(vehicle_id: int, t_us: int, pose: np.ndarray) -> np.ndarray:
        offset = offset_of(vehicle_id, t_us, pose)
        spoofed[vehicle_id] = max(spoofed.get(vehicle_id, 0.0), float(np.hypot(*offset)))
        return offset

    world.faults.spoof_offset_m = recording
    world.advance(round(DURATION_S * 1e6))
    assert spoofed.pop(LIAR) > 0.5 * (DURATION_S - LIE_START_S) * 0.9, spoofed  # 0.5 m/s from the lie on
    assert set(spoofed) == set(world.vehicle_ids()) - {LIAR} and max(spoofed.values()) == 0.0, spoofed


def test_the_oracle_cuts_the_liars_broadcasts_at_the_delay_asked_for():
    runs = cases([1, 2], ("drift",), silenced=(0.0, 5.0))
    silenced = [c for c in runs if c.silenced_after_s is not None]
    assert [c.name for c in silenced if c.seed == 1] == ["drift-silenced-0s-seed1", "drift-silenced-5s-seed1"]
    assert len({c.name for c in runs}) == len(runs)
    faults = liar_config(silenced[1]).faults
    cut = [f for f in faults if f.kind == "loss"]
    assert len(cut) == 1 and cut[0].src == f"v{LIAR}" and cut[0].dst == "v*" and cut[0].percent == 100.0
    assert cut[0].start_s == LIE_START_S + 5.0 and not liar_config(silenced[1]).vehicle.monitor.enabled
    assert any(f.kind == "lie" for f in faults)


def test_the_jamming_that_ends_flies_with_the_monitor_on_and_off_and_ends():
    """The control for the neighbours' say on GNSS resets: the same six blackouts as the jamming
    control, ended, with the monitor on and off (no liar: no verdict, only the say differs)."""
    ended = [c for c in cases([1]) if c.condition == "jamming-ends"]
    assert sorted(c.defence for c in ended) == [False, True]
    jammed, ending = (liar_config(Case(k, True, 1)).faults for k in ("jamming", "jamming-ends"))
    assert [(f.vehicle, f.start_s) for f in ending] == [(f.vehicle, f.start_s) for f in jammed]
    assert all(f.for_s is None for f in jammed) and all(f.for_s == JAMMING_ENDS_AFTER_S for f in ending)
    assert LIE_START_S + JAMMING_ENDS_AFTER_S < DURATION_S  # the receivers come back inside the run


@pytest.mark.parametrize(("value", "said"), [("soon", "not a number"), ("-1", "outside"), ("51", "outside")])
def test_a_bad_oracle_delay_is_refused_in_one_line(tmp_path, value, said):
    result = CliRunner().invoke(app, ["experiment", "liar", "--out", str(tmp_path), "--silenced", value])
    assert result.exit_code == 1 and said in result.output and len(result.output.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())  # refused before anything flew


def _run(path, errors: dict[int, float], events: list[dict]):
    """A run directory with a constant position error per vehicle every second and these events."""
    path.mkdir()
    rows = ["t_s,vehicle,err_pos_m"] + [f"{t}.0,{v},{e}" for t in range(60) for v, e in errors.items()]
    (path / "metrics.csv").write_text("\n".join(rows) + "\n")
    (path / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))
    return path


def test_the_summary_scores_honest_vehicles_the_liar_and_false_alarms_apart(tmp_path):
    honest, rangers = dict.fromkeys(range(1, 9), 0.2), [v for v in rangers_of_liar(1) if v != LIAR]
    first = rangers_of_liar(1)
    late = max(rangers, key=first.get)  # told by the others before it ranged the liar
    distrust = [
        {
            "event": "neighbour_distrusted",
            "t_s": first[v] + (-3.0 if v == late else 1.5),
            "vehicle": v,
            "neighbour": LIAR,
        }
        for v in rangers
    ]
    distrust += [
        {"event": "neighbour_distrusted", "t_s": 20.0, "vehicle": 4, "neighbour": 5},  # an honest one accused
        {"event": "neighbour_distrusted", "t_s": 21.0, "vehicle": LIAR, "neighbour": 2},  # by the liar itself
    ]
    runs = {
        Case("clean", False, 1): _run(tmp_path / "clean", honest, []),
        Case("gross", True, 1): _run(tmp_path / "gross", {**dict.fromkeys(range(1, 9), 0.3), LIAR: 0.5}, distrust),
    }
    row = summarize(runs)["conditions"]["gross-defended"]
    assert row["honest_rmse_vs_clean_mean"] == pytest.approx(1.5)  # the liar's own error left out
    assert row["liar_own_rmse_m_mean"] == pytest.approx(0.5)
    assert row["false_alarms"] == 2 and row["false_alarms_by_the_liar"] == 1
    assert row["rangers_that_distrusted_the_liar"] == f"{len(rangers)} of {len(rangers)}"
    assert row["distrusted_before_ranging_it"] == 1
    assert row["detection_s_median"] == pytest.approx(1.5) and row["detection_s_max"] == pytest.approx(1.5)


def test_the_registry_names_each_experiments_own_conditions():
    from experiments import insiders, liar
    from experiments.registry import INSIDER_CONDITIONS, LIAR_PROFILES

    assert INSIDER_CONDITIONS == tuple(insiders.CONDITIONS) and LIAR_PROFILES == liar.PROFILES
    from experiments import mrclam
    from experiments.registry import MRCLAM_VARIANTS

    assert MRCLAM_VARIANTS == tuple(mrclam.VARIANTS)
