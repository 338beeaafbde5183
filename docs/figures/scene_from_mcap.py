"""Re-draw a run's recorded 3-D scene at one sim time, as seen from above, with matplotlib: what the
Foxglove/Lichtblick 3-D panel shows from run.mcap (the terrain model's texture, each vehicle's true
and estimated pose, 3-sigma ellipse and trails, the ranging lines, the SLAM maps and the fault zones).
It reads only run.mcap (and decodes the terrain's GLB), so it also checks that the recorded scene
lines up. Not a screenshot of the app: no display here.

    python docs/figures/scene_from_mcap.py RUN_DIR OUT.png [--at 20] [--span 60]
"""

from __future__ import annotations

import argparse
import json
import struct
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap_protobuf.decoder import DecoderFactory  # noqa: E402


def latest_before(run_mcap: Path, at_ns: int) -> dict:
    """The last SceneUpdate entities of each topic up to ``at_ns`` (deletions applied)."""
    entities: dict[str, dict] = {}
    with run_mcap.open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        topics = [c.topic for c in reader.get_summary().channels.values() if c.message_encoding == "protobuf"]
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=topics, ending_at=at_ns):
            if hasattr(decoded, "entities"):
                scene = entities.setdefault(channel.topic, {})
                for deletion in decoded.deletions:
                    scene.pop(deletion.id, None)
                for entity in decoded.entities:
                    scene[entity.id] = (message.log_time, entity)
    return entities


def glb_texture(glb: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The texture image and the quad's corners (4, 3) of a terrain GLB (groundstation.terrain_model)."""
    json_length = struct.unpack_from("<I", glb, 12)[0]
    document = json.loads(glb[20 : 20 + json_length])
    binary = glb[28 + json_length :]

    def view(index: int) -> bytes:
        v = document["bufferViews"][index]
        return binary[v["byteOffset"] : v["byteOffset"] + v["byteLength"]]

    corners = np.frombuffer(view(document["accessors"][0]["bufferView"]), "<f4").reshape(4, 3)
    image = cv2.imdecode(np.frombuffer(view(document["images"][0]["bufferView"]), np.uint8), cv2.IMREAD_UNCHANGED)
    return image, corners


def draw(run_dir: Path, out: Path, at_s: float, span_m: float) -> None:
    at_ns = round(at_s * 1e9)
    entities = latest_before(run_dir / "run.mcap", at_ns)
    fig, ax = plt.subplots(figsize=(8, 8), facecolor="#202020")
    ax.set_facecolor("#303030")
    for _, entity in entities.get("/terrain", {}).values():
        image, corners = glb_texture(entity.models[0].data)
        x0, x1 = corners[:, 0].min(), corners[:, 0].max()
        y0, y1 = -corners[:, 2].max(), -corners[:, 2].min()  # glTF (x, 0, -y): the panel's Z-up turn
        ax.imshow(image, cmap="gray", extent=(x0, x1, y0, y1), origin="upper", alpha=0.8, zorder=0)
    for topic in ("/trails", "/zones", "/landmarks", "/ranging", "/scene"):
        for log_time, entity in entities.get(topic, {}).values():
            lifetime = entity.lifetime.seconds * 1e9 + entity.lifetime.nanos if entity.HasField("lifetime") else 0
            if lifetime and log_time + lifetime < at_ns:
                continue  # expired, as the panel drops it
            for line in entity.lines:
                xy = np.array([(p.x, p.y) for p in line.points])
                c = (line.color.r, line.color.g, line.color.b, line.color.a)
                if topic == "/trails":
                    ax.plot(xy[:, 0], xy[:, 1], color=c, lw=1.0, zorder=1)
                elif line.type == 2:  # LINE_LIST: segments
                    for a, b in zip(xy[::2], xy[1::2]):
                        ax.plot([a[0], b[0]], [a[1], b[1]], color=c, lw=0.8 if topic != "/ranging" else 1.2, zorder=2)
                else:
                    closed = np.vstack([xy, xy[:1]]) if line.type == 1 else xy
                    ax.plot(closed[:, 0], closed[:, 1], color=c, lw=1.5, zorder=3)
            for arrow in entity.arrows:
                p, q = arrow.pose.position, arrow.pose.orientation
                yaw = 2 * np.arctan2(q.z, q.w)
                c = (arrow.color.r, arrow.color.g, arrow.color.b)
                ax.arrow(p.x, p.y, 3 * np.cos(yaw), 3 * np.sin(yaw), color=c, width=0.5, zorder=4)
            for text in entity.texts:
                p = text.pose.position
                ax.text(p.x + 1.5, p.y + 1.5, text.text, color="white", fontsize=9, zorder=5)
    scene = [e for _, e in entities.get("/scene", {}).values()]
    centre = np.mean([[e.arrows[1].pose.position.x, e.arrows[1].pose.position.y] for e in scene], axis=0)
    ax.set_xlim(centre[0] - span_m / 2, centre[0] + span_m / 2)
    ax.set_ylim(centre[1] - span_m / 2, centre[1] + span_m / 2)
    ax.set_aspect("equal")
    ax.tick_params(colors="#bbbbbb")
    ax.set_xlabel("x east [m]", color="#bbbbbb")
    ax.set_ylabel("y north [m]", color="#bbbbbb")
    ax.set_title(f"{run_dir.name}: the recorded scene at {at_s:g} s", color="white")
    fig.tight_layout()
    fig.savefig(out, dpi=110, facecolor=fig.get_facecolor())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("out", type=Path)
    parser.add_argument("--at", type=float, default=20.0, help="sim time (s)")
    parser.add_argument("--span", type=float, default=120.0, help="side of the view (m)")
    args = parser.parse_args()
    draw(args.run_dir, args.out, args.at, args.span)


if __name__ == "__main__":
    main()
