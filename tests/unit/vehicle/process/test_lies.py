"""What a misbehaving vehicle tells its neighbours (vehicle.process.lies), from the plan's lie and
accuse faults: which are active for whom, what a stale lie tells."""

import numpy as np
import pytest

from bus.faults import check_fault


def test_a_lie_must_say_something_false_and_names_a_vehicle_of_the_swarm():
    from bus.faults import Lie
    from vehicle.process.lies import active_lies

    with pytest.raises(ValueError, match="would tell the truth"):
        Lie(vehicle=3)
    lie = Lie(vehicle=3, offset_m=(30.0, -30.0), drift_mps=0.15, heading_deg=90.0, start_s=10.0, for_s=60.0)
    assert lie.offset_at(20.0) == pytest.approx([30.0, -28.5])
    with pytest.raises(ValueError, match="vehicle 3 does not exist"):
        check_fault(lie, 2)
    assert active_lies((lie,), 3, 9.99) == [] and active_lies((lie,), 3, 10.0) == [lie]
    assert active_lies((lie,), 2, 20.0) == [] and active_lies((lie,), 3, 70.0) == []


def test_an_accusation_fault_names_other_vehicles_of_the_swarm():
    from bus.faults import Accuse
    from bus.mavlink_codec import MAX_ACCUSED
    from vehicle.process.lies import false_accusations

    with pytest.raises(ValueError, match="would accuse itself"):
        Accuse(vehicle=3, names=(1, 3))
    with pytest.raises(ValueError):
        Accuse(vehicle=3, names=())
    with pytest.raises(ValueError):
        Accuse(vehicle=3, names=tuple(range(4, 5 + MAX_ACCUSED)))  # more than one broadcast carries
    accuse = Accuse(vehicle=3, names=(1, 2), start_s=5.0, for_s=10.0)
    with pytest.raises(ValueError, match="--names v2 does not exist"):
        check_fault(Accuse(vehicle=1, names=(2,)), 1)
    assert false_accusations((accuse,), 3, 4.9) == frozenset() and false_accusations((accuse,), 3, 5.0) == {1, 2}
    assert false_accusations((accuse,), 2, 6.0) == frozenset() and false_accusations((accuse,), 3, 15.0) == frozenset()


def test_a_stale_lie_tells_the_estimate_of_that_long_before_stamped_now():
    from bus.estimate import PoseEstimate
    from bus.faults import Lie
    from vehicle.process.lies import told

    lie = Lie(vehicle=3, stale_s=5.0)
    past = [PoseEstimate(3, k * 200_000, np.array([k, 0.0, 0.0]), np.eye(3) * (1 + k)) for k in range(60)]
    now = past[-1]
    said = told(now, [lie], past)
    assert said.stamp_us == now.stamp_us and said.pose[0] == 59 - 25 and said.pose_cov[0, 0] == 1 + 59 - 25
    assert told(past[3], [lie], past[:4]).pose[0] == 0  # not 5 s of past yet: the oldest there is
