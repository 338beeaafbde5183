"""What the recording's scene channels draw (groundstation.recording), as Foxglove messages built
from the ground station's scores, the world's ranging pairs, a SLAM vehicle's map and the plan's
fault zones: pure functions of their inputs and of ``fm``, the SDK's message module (imported by the
caller: only the ground station loads the SDK)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from groundstation import scene_primitives as sp
from groundstation.scene_primitives import ELLIPSE_POINTS, ellipse_xy, zone_colour
from groundstation.scoring import Score

RANGING_LIFETIME_NS = 1_000_000_000
TRUE_RGB, ESTIMATED_RGB = (0.1, 0.8, 0.2), (0.2, 0.4, 1.0)
LANDMARK_RGBA = (1.0, 0.85, 0.2, 0.45)


def heights_m(s: Score) -> tuple[float, float]:
    """Where the scene draws a vehicle's estimate and truth, up (m): a vehicle that estimates its height
    (a UAV) at its estimated and its true height above its launch point, one that flies level on the
    ground (0, 0)."""
    if math.isnan(s.altitude_error_m):
        return 0.0, 0.0
    estimated = -float(s.estimate.position_m[2])  # ODOMETRY's z is down
    return estimated, estimated - s.altitude_error_m


def vehicle_entity(fm: Any, s: Score) -> Any:
    """A vehicle in the scene: its estimated and true pose arrows (at their heights, ``heights_m``), its
    3-sigma ellipse at the estimate's height and its label."""
    est, truth = s.estimate, s.truth_pose
    est_z, true_z = heights_m(s)
    estimate_pose = sp.pose(fm, est.position_m[0], est.position_m[1], est.yaw_rad, est_z)
    ring = ellipse_xy(np.asarray(est.position_m[:2]), s.pose_covariance[:2, :2])
    return fm.SceneEntity(
        timestamp=sp.stamp(fm, s.stamp_us),
        frame_id="world",
        id=f"vehicle-{s.vehicle_id}",
        arrows=[
            sp.arrow(fm, estimate_pose, ESTIMATED_RGB),
            sp.arrow(fm, sp.pose(fm, truth[0], truth[1], truth[2], true_z), TRUE_RGB),
        ],
        lines=[sp.loop(fm, ring, (*ESTIMATED_RGB, 0.8), 2.0, est_z)],
        texts=[sp.label(fm, estimate_pose, f"v{s.vehicle_id}", (1.0, 1.0, 1.0, 1.0))],
    )


def terrain_update(fm: Any, glb: bytes, stamp_us: int) -> Any:
    """The terrain model (a GLB, groundstation.terrain_model) as one scene entity."""
    model = fm.ModelPrimitive(
        pose=sp.pose(fm, 0.0, 0.0, 0.0),
        scale=fm.Vector3(x=1.0, y=1.0, z=1.0),
        media_type="model/gltf-binary",
        data=glb,
    )
    entity = fm.SceneEntity(timestamp=sp.stamp(fm, stamp_us), frame_id="world", id="terrain", models=[model])
    return fm.SceneUpdate(entities=[entity])


def ranging_update(fm: Any, stamp_us: int, pairs: np.ndarray, positions: dict[int, np.ndarray]) -> Any:
    """Lines between the ``positions`` (vehicle id -> (2,) m) of each ranging pair (m, 2) of a tick,
    each pair once, shown for RANGING_LIFETIME_NS."""
    points = []
    for a, b in {tuple(sorted(p)) for p in pairs.tolist()}:
        if a in positions and b in positions:
            points += [fm.Point3(x=float(v[0]), y=float(v[1]), z=0.0) for v in (positions[a], positions[b])]
    line = fm.LinePrimitive(
        type=fm.LinePrimitiveLineType.LineList,
        thickness=1.0,
        scale_invariant=True,
        points=points,
        color=fm.Color(r=0.9, g=0.9, b=0.9, a=0.6),
    )
    lifetime = fm.Duration(sec=RANGING_LIFETIME_NS // 1_000_000_000, nsec=0)
    entity = fm.SceneEntity(
        timestamp=sp.stamp(fm, stamp_us), frame_id="world", id="ranging", lifetime=lifetime, lines=[line]
    )
    return fm.SceneUpdate(entities=[entity])


def trail_entity(fm: Any, vehicle_id: int, stamp_us: int, trail: list[tuple[int, tuple, tuple]]) -> Any:
    """A vehicle's true (green) and estimated (blue) trail through its points (stamp us, true xyz,
    estimated xyz; z up, ``heights_m``), oldest first."""
    lines = [
        fm.LinePrimitive(
            type=fm.LinePrimitiveLineType.LineStrip,
            thickness=1.5,
            scale_invariant=True,
            points=[fm.Point3(x=float(p[which][0]), y=float(p[which][1]), z=float(p[which][2])) for p in trail],
            color=fm.Color(r=rgb[0], g=rgb[1], b=rgb[2], a=0.7),
        )
        for which, rgb in ((1, TRUE_RGB), (2, ESTIMATED_RGB))
    ]
    return fm.SceneEntity(timestamp=sp.stamp(fm, stamp_us), frame_id="world", id=f"trail-{vehicle_id}", lines=lines)


def landmark_update(fm: Any, maps: list[Any]) -> Any:
    """SLAM vehicles' maps (bus.landmark_map.LandmarkMap), an entity each (``landmark_entity``), in
    one update: a viewer that seeks in a recording shows the newest message of a topic."""
    return fm.SceneUpdate(entities=[landmark_entity(fm, lmap) for lmap in maps])


def landmark_entity(fm: Any, lmap: Any) -> Any:
    """A SLAM vehicle's map: one line list of 3-sigma ellipses on the ground, or a 3-D map's 3-sigma
    ellipsoids at the landmarks' heights."""
    stamp, entity_id = sp.stamp(fm, lmap.stamp_us), f"landmarks-{lmap.vehicle_id}"
    if lmap.height_m is not None:
        centres = np.column_stack([lmap.xy_m, lmap.height_m])
        spheres = [sp.ellipsoid_sphere(fm, c, cov, LANDMARK_RGBA) for c, cov in zip(centres, lmap.covariance3_m2)]
        return fm.SceneEntity(timestamp=stamp, frame_id="world", id=entity_id, spheres=spheres)
    points = []
    for xy, cov in zip(lmap.xy_m, lmap.covariance_m2):
        ring = ellipse_xy(np.asarray(xy), np.asarray(cov))[:: ELLIPSE_POINTS // 12]
        for a, b in zip(ring, np.roll(ring, -1, axis=0)):
            points += [
                fm.Point3(x=float(a[0]), y=float(a[1]), z=0.0),
                fm.Point3(x=float(b[0]), y=float(b[1]), z=0.0),
            ]
    return fm.SceneEntity(
        timestamp=stamp,
        frame_id="world",
        id=entity_id,
        lines=[
            fm.LinePrimitive(
                type=fm.LinePrimitiveLineType.LineList,
                thickness=1.0,
                scale_invariant=True,
                points=points,
                color=fm.Color(r=LANDMARK_RGBA[0], g=LANDMARK_RGBA[1], b=LANDMARK_RGBA[2], a=0.8),
            )
        ],
    )


def zone_update(fm: Any, stamp_us: int, active: dict[str, Any], ended: set[str]) -> Any:
    """The ``active`` fault zones (name -> a fault with a centre and a radius) as labelled circles,
    and the deletion of those that ``ended``."""
    stamp = sp.stamp(fm, stamp_us)
    deletions = [fm.SceneEntityDeletion(timestamp=stamp, id=f"zone-{n}") for n in ended]
    entities = []
    for name, fault in active.items():
        angle = np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False)
        x = fault.center_m[0] + fault.radius_m * np.cos(angle)
        y = fault.center_m[1] + fault.radius_m * np.sin(angle)
        rgba = (*zone_colour(fault.kind), 0.9)
        centre = sp.pose(fm, fault.center_m[0], fault.center_m[1], 0.0)
        entities.append(
            fm.SceneEntity(
                timestamp=stamp,
                frame_id="world",
                id=f"zone-{name}",
                lines=[sp.loop(fm, np.stack([x, y], axis=1), rgba, 3.0)],
                texts=[sp.label(fm, centre, f"{fault.kind} {name}", rgba)],
            )
        )
    return fm.SceneUpdate(deletions=deletions, entities=entities)
