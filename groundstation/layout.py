"""The Foxglove layout that opens a swarmloc run (live or run.mcap) in one step: the scene (true and
estimated poses, 3-sigma ellipses) beside the position error and NEES of every vehicle and the event
log, the GNSS health and loop overruns, the ranging pairs and, under a camera swarm, the terrain.
Built with the Foxglove SDK's layout classes; ``deploy/foxglove-layout.json`` is its output
for five vehicles (a test keeps the two equal)."""

from __future__ import annotations


def swarm_layout(vehicles: int = 5) -> str:
    """The layout as JSON (Foxglove or Lichtblick: Layouts, Import from file)."""
    from foxglove import layouts as fl

    from groundstation.recording import pose_topic

    scene = fl.ThreeDeePanel(
        title="swarm",
        config=fl.ThreeDeeConfig(
            follow_tf="world",
            topics={
                "/scene": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/zones": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/landmarks": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/ranging": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/trails": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                "/terrain": fl.BaseRendererSceneUpdateTopicSettings(visible=True),
                **{
                    pose_topic(v, "truth"): fl.BaseRendererPoseTopicSettings(visible=False, type="arrow")
                    for v in range(1, vehicles + 1)
                },
            },
        ),
    )

    def per_vehicle(topic: str, field: str, label: str, extra: tuple[tuple[str, str], ...] = ()) -> fl.PlotPanel:
        series = [
            fl.PlotSeries(value=f"{topic}{{vehicle=={v}}}.{field}", label=f"v{v}", enabled=True)
            for v in range(1, vehicles + 1)
        ]
        series += [fl.PlotSeries(value=value, label=name, enabled=True) for name, value in extra]
        return fl.PlotPanel(title=label, config=fl.PlotConfig(paths=series, show_legend=True, y_axis_label=label))

    band = (("95 % low", "/metrics{vehicle==1}.nees_band_low"), ("95 % high", "/metrics{vehicle==1}.nees_band_high"))
    swarm = (("swarm RMS", "/swarm.rms_error_m"),)
    plots = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(content=per_vehicle("/metrics", "err_pos_m", "position error [m]", swarm)),
            fl.SplitItem(content=per_vehicle("/metrics", "nees", "pose NEES (3 dof)", band)),
            fl.SplitItem(content=per_vehicle("/health", "gnss_test_ratio", "GNSS test ratio")),
            fl.SplitItem(content=per_vehicle("/loop", "overruns", "loop overruns")),
            fl.SplitItem(content=fl.LogPanel(title="events", config=fl.LogConfig(topic_to_render="/events"))),
        ],
    )
    layout = fl.Layout(
        content=fl.SplitContainer(
            direction="row", items=[fl.SplitItem(proportion=1.4, content=scene), fl.SplitItem(content=plots)]
        )
    )
    return layout.to_json()
