"""The layouts that open a swarmloc run (live or run.mcap) in one step, for Foxglove and for Lichtblick:
the scene (true and estimated poses, 3-sigma ellipses, trails, ranging lines, zones, landmarks and,
under a camera swarm, the terrain) framed on the swarm's area, beside the position error and NEES of
every vehicle, the GNSS health, the loop overruns and the event log. One description, two shapes:
Foxglove's (``{version, content}``, built with the Foxglove SDK's layout classes) and Lichtblick's
(``{configById, layout, globalVariables, userNodes, playbackConfig}``, panel ids ``3D!...``,
``Plot!...``, ``RosOut!...``: what its layout import accepts). Every plot series reads its x axis
from the receive time, which is the run's sim time (the live server broadcasts it; a recording's log
times are it). ``deploy/foxglove-layout.json`` and ``deploy/lichtblick-layout.json`` are the output for
the default five-vehicle world (a test keeps them equal); each run directory with run.mcap gets its
own pair (``layout-foxglove.json``, ``layout-lichtblick.json``)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from bus.config import WorldConfig
from bus.pads import start_pads
from bus.statistics import chi2_band
from groundstation.shown import SHOWN

FOXGLOVE_FILE, LICHTBLICK_FILE = "layout-foxglove.json", "layout-lichtblick.json"
SCENE_TOPICS = ("/scene", "/zones", "/landmarks", "/ranging", "/trails", "/terrain")
FOVY_DEG, PHI_DEG, THETA_DEG = 45.0, 30.0, 0.0


@dataclass(frozen=True)
class Framing:
    """Where the 3-D panel looks: the swarm area's centre (m) and the radius (m) to show around it."""

    centre_m: tuple[float, float]
    radius_m: float

    def camera(self) -> dict[str, object]:
        """The 3-D panel's camera state (both viewers' keys): the area's circle fills the view."""
        distance = 1.15 * self.radius_m / math.tan(math.radians(FOVY_DEG) / 2.0)
        return {
            "distance": round(distance, 1),
            "perspective": True,
            "phi": PHI_DEG,
            "target": [0.0, 0.0, 0.0],
            "targetOffset": [round(self.centre_m[0], 1), round(self.centre_m[1], 1), 0.0],
            "targetOrientation": [0.0, 0.0, 0.0, 1.0],
            "thetaOffset": THETA_DEG,
            "fovy": FOVY_DEG,
            "near": 0.5,
            "far": round(max(5000.0, 4.0 * distance), 1),
        }


def framing(world: WorldConfig) -> Framing:
    """The area the world's vehicles fly over: its start pads (bus.pads) and a trajectory's reach
    around each (a figure-8 spans two circles of ``radius_m``)."""
    pads = start_pads(world.vehicles, world.spacing_m)
    low, high = pads.min(axis=0), pads.max(axis=0)
    centre = (low + high) / 2.0
    return Framing((float(centre[0]), float(centre[1])), float(np.hypot(*(high - low))) / 2.0 + 2.0 * world.radius_m)


@dataclass(frozen=True)
class Plot:
    key: str
    title: str
    series: tuple[tuple[str, str], ...]  # (label, message path or a number: a reference line)


def _plots(vehicles: int, heights: bool = False) -> tuple[Plot, ...]:
    """The plots beside the scene: per vehicle up to ``SHOWN`` vehicles (with each one's height error
    where the vehicles estimate their ``heights``), the swarm's RMS and largest error and mean NEES
    (against the band of a mean of ``vehicles`` NEES) beyond."""
    if vehicles > SHOWN:
        low, high = chi2_band(3, runs=vehicles)
        return (
            Plot(
                "error",
                "position error [m]",
                (("swarm RMS", "/swarm.rms_error_m"), ("swarm max", "/swarm.max_error_m")),
            ),
            Plot(
                "nees",
                f"pose NEES (3 dof), mean of the {vehicles} vehicles",
                (("swarm mean", "/swarm.mean_nees"), ("95 % low", f"{low:.4f}"), ("95 % high", f"{high:.4f}")),
            ),
        )
    low, high = chi2_band(3)
    ids = range(1, vehicles + 1)
    height = Plot("height", "height error [m]", tuple((f"v{v}", f"{_topic(v, 'metrics')}.err_alt_m") for v in ids))
    return (
        Plot(
            "error",
            "position error [m]",
            tuple((f"v{v}", f"{_topic(v, 'metrics')}.err_pos_m") for v in ids) + (("swarm RMS", "/swarm.rms_error_m"),),
        ),
        *((height,) if heights else ()),
        Plot(
            "nees",
            "pose NEES (3 dof)",
            tuple((f"v{v}", f"{_topic(v, 'metrics')}.nees") for v in ids)
            + (("95 % low", f"{low:.4f}"), ("95 % high", f"{high:.4f}")),
        ),
        Plot("gnss", "GNSS test ratio", tuple((f"v{v}", f"{_topic(v, 'health')}.gnss_test_ratio") for v in ids)),
        Plot("loop", "loop overruns", tuple((f"v{v}", f"{_topic(v, 'loop')}.overruns") for v in ids)),
    )


def _topic(vehicle_id: int, kind: str) -> str:
    from groundstation.recording import pose_topic

    return pose_topic(vehicle_id, kind)


def _truth_topics(vehicles: int) -> list[str]:
    """The true poses' topics (hidden at open: the scene draws truth and estimate already)."""
    return [_topic(v, "truth") for v in range(1, vehicles + 1)]


def _scene_topics(vehicles: int) -> dict[str, dict[str, object]]:
    hidden = {topic: {"visible": False, "type": "arrow"} for topic in _truth_topics(vehicles)}
    return {**{t: {"visible": True} for t in SCENE_TOPICS}, **hidden}


def foxglove_layout(vehicles: int, view: Framing, heights: bool = False) -> str:
    """The layout as Foxglove reads it (Layouts, Import from file), built with the SDK's classes."""
    from foxglove import layouts as fl

    truth = set(_truth_topics(vehicles))
    topics = {
        topic: (
            fl.BaseRendererPoseTopicSettings(visible=False, type="arrow")
            if topic in truth
            else fl.BaseRendererSceneUpdateTopicSettings(visible=True)
        )
        for topic in _scene_topics(vehicles)
    }
    camera = view.camera()
    scene = fl.ThreeDeePanel(
        title="swarm",
        config=fl.ThreeDeeConfig(
            follow_tf="world",
            follow_mode="follow-none",
            topics=topics,
            camera_state=fl.ThreeDeeCameraState(
                distance=camera["distance"],
                perspective=True,
                phi=PHI_DEG,
                target=(0.0, 0.0, 0.0),
                target_offset=tuple(camera["targetOffset"]),
                target_orientation=(0.0, 0.0, 0.0, 1.0),
                theta_offset=THETA_DEG,
                fovy=FOVY_DEG,
                near=0.5,
                far=camera["far"],
            ),
        ),
    )
    plots = [
        fl.PlotPanel(
            title=plot.title,
            config=fl.PlotConfig(
                paths=[
                    fl.PlotSeries(value=value, label=label, enabled=True, timestamp_method="receiveTime")
                    for label, value in plot.series
                ],
                show_legend=True,
                legend_display="left",
                show_plot_values_in_legend=True,
                y_axis_label=plot.title,
            ),
        )
        for plot in _plots(vehicles, heights)
    ]
    events = fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render="/events"))
    column = fl.SplitContainer(direction="column", items=[fl.SplitItem(content=p) for p in [*plots, events]])
    layout = fl.Layout(
        content=fl.SplitContainer(
            direction="row", items=[fl.SplitItem(proportion=1.4, content=scene), fl.SplitItem(content=column)]
        )
    )
    return layout.to_json()


def lichtblick_layout(vehicles: int, view: Framing, heights: bool = False) -> str:
    """The layout as Lichtblick reads it (Layouts, Import, or ``?layoutUrl=``)."""
    return lichtblick_document("swarm", view.camera(), _scene_topics(vehicles), _plots(vehicles, heights), "/events")


def lichtblick_document(
    scene_title: str,
    camera: dict[str, object],
    topics: dict[str, dict],
    plots: tuple[Plot, ...],
    log_topic: str | None,
    follow: tuple[str, str] = ("world", "follow-none"),
    hidden_frames: tuple[str, ...] = (),
    preload_transforms: bool = False,
) -> str:
    """A Lichtblick layout: a 3-D panel titled ``scene_title`` looking from ``camera`` (``Framing.camera``'s
    keys) at ``topics`` (topic -> its settings), following the frame ``follow`` [0] in the mode
    ``follow`` [1] (its axes and its line to the parent not drawn for the frames ``hidden_frames``),
    beside a column of ``plots`` and, with ``log_topic``, a log panel of that topic under them;
    ``preload_transforms``: the panel reads a recording's transforms ahead (what Lichtblick recommends,
    with an alert, when a recording has a transform topic)."""
    config: dict[str, dict] = {
        f"3D!{scene_title}": {
            "lichtblickPanelTitle": scene_title,
            "cameraState": camera,
            "followTf": follow[0],
            "followMode": follow[1],
            "scene": {"transforms": {"enablePreloading": True}} if preload_transforms else {},
            "transforms": {f"frame:{frame}": {"visible": False} for frame in hidden_frames},
            "topics": topics,
            "layers": {},
            "publish": {"type": "point", "poseTopic": "/move_base_simple/goal", "pointTopic": "/clicked_point"},
            "imageMode": {},
        }
    }
    for plot in plots:
        config[f"Plot!{plot.key}"] = {
            "lichtblickPanelTitle": plot.title,
            "paths": [
                {"value": value, "label": label, "enabled": True, "timestampMethod": "receiveTime"}
                for label, value in plot.series
            ],
            "showLegend": True,
            "legendDisplay": "left",
            "showPlotValuesInLegend": True,
            "showXAxisLabels": True,
            "showYAxisLabels": True,
            "isSynced": True,
            "xAxisVal": "timestamp",
            "yAxisLabel": plot.title,
            "sidebarDimension": 240,
        }
    panels = [f"Plot!{p.key}" for p in plots]
    if log_topic is not None:
        config["RosOut!events"] = {
            "lichtblickPanelTitle": "events",
            "searchTerms": [],
            "minLogLevel": 1,
            "topicToRender": log_topic,
        }
        panels.append("RosOut!events")
    column: object = panels[-1]
    for count, panel in enumerate(reversed(panels[:-1]), start=1):  # each split gives its first an equal share
        column = {"direction": "column", "first": panel, "second": column, "splitPercentage": 100.0 / (count + 1)}
    layout = {"direction": "row", "first": f"3D!{scene_title}", "second": column, "splitPercentage": 58.0}
    data = {
        "configById": config,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1.0},
        "layout": layout,
    }
    return json.dumps(data, indent=2) + "\n"


def swarm_layouts(world: WorldConfig, heights: bool = False) -> dict[str, str]:
    """The run's layouts by file name (``FOXGLOVE_FILE``, ``LICHTBLICK_FILE``), framed on its world;
    with a height error plot where its vehicles estimate their ``heights``."""
    view = framing(world)
    return {
        FOXGLOVE_FILE: foxglove_layout(world.vehicles, view, heights),
        LICHTBLICK_FILE: lichtblick_layout(world.vehicles, view, heights),
    }
