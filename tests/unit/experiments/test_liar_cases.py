"""The liar experiment's cases: the spoofer of the ``spoofed`` profile spoofs the liar and nobody
else, and the oracle rows cut the liar's V2V at the delay asked for."""

import numpy as np
import pytest
from typer.testing import CliRunner

from cli.main import app
from experiments.liar import DURATION_S, LIAR, LIE_START_S, Case, cases, liar_config
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
    assert cut[0].start_s == LIE_START_S + 5.0 and not liar_config(silenced[1]).vehicle.neighbour_monitor
    assert any(f.kind == "lie" for f in faults)


@pytest.mark.parametrize(("value", "said"), [("soon", "not a number"), ("-1", "outside"), ("51", "outside")])
def test_a_bad_oracle_delay_is_refused_in_one_line(tmp_path, value, said):
    result = CliRunner().invoke(app, ["experiment", "liar", "--out", str(tmp_path), "--silenced", value])
    assert result.exit_code == 1 and said in result.output and len(result.output.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())  # refused before anything flew
