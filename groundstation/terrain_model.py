"""The terrain image under a camera swarm as a 3-D model the Foxglove/Lichtblick 3-D panel draws: one
flat textured quad in binary glTF 2.0 (GLB), unlit, the image as its PNG texture.

glTF is Y-up and the 3-D panel turns every glTF scene into its Z-up frame (a +90 degree rotation
about x, as ROS REP-0103), so the world point (x, y) on the ground is the glTF vertex (x, 0, -y).
The image's centre is the world origin and its rows grow southwards (sim.terrain). Pure.
"""

from __future__ import annotations

import json
import struct

import cv2
import numpy as np

GLB_MAGIC, GLB_VERSION = 0x46546C67, 2
CHUNK_JSON, CHUNK_BIN = 0x4E4F534A, 0x004E4942
FLOAT, UNSIGNED_SHORT = 5126, 5123
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
LINEAR = 9729
MAX_TEXTURE_PX = 1024


def terrain_glb(image: np.ndarray, width_m: float, height_m: float) -> bytes:
    """A GLB of the grey (H, W) uint8 ``image`` lying on the ground, ``width_m`` x ``height_m``
    metres, centred on the origin; the texture scaled down to at most MAX_TEXTURE_PX a side."""
    scale = min(1.0, MAX_TEXTURE_PX / max(image.shape))
    if scale < 1.0:
        size = (max(1, round(image.shape[1] * scale)), max(1, round(image.shape[0] * scale)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    ok, png = cv2.imencode(".png", image)
    if not ok:
        raise ValueError("the terrain image could not be encoded as PNG")
    half_w, half_h = width_m / 2, height_m / 2
    # corners NW, NE, SE, SW: world (x, y) -> glTF (x, 0, -y); texture (u, v) from the image's top left
    positions = np.array(
        [[-half_w, 0, -half_h], [half_w, 0, -half_h], [half_w, 0, half_h], [-half_w, 0, half_h]], np.float32
    )
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    indices = np.array([0, 3, 2, 0, 2, 1], np.uint16)  # counter-clockwise seen from above (+y)
    blobs = [positions.tobytes(), uvs.tobytes(), indices.tobytes(), png.tobytes()]
    views, offset = [], 0
    for blob, target in zip(blobs, (ARRAY_BUFFER, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, None)):
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(blob)}
        views.append(view | ({"target": target} if target else {}))
        offset += _padded(len(blob))
    document = _document(views, offset, positions)
    binary = b"".join(blob + b"\0" * (_padded(len(blob)) - len(blob)) for blob in blobs)
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (_padded(len(text)) - len(text))
    total = 12 + 8 + len(text) + 8 + len(binary)
    return b"".join(
        [
            struct.pack("<III", GLB_MAGIC, GLB_VERSION, total),
            struct.pack("<II", len(text), CHUNK_JSON),
            text,
            struct.pack("<II", len(binary), CHUNK_BIN),
            binary,
        ]
    )


def _document(views: list[dict], buffer_bytes: int, positions: np.ndarray) -> dict:
    """The glTF JSON: one node, one mesh of one textured, unlit, double-sided quad; accessors 0-2 are
    the positions, texture coordinates and indices, buffer view 3 the PNG."""
    return {
        "asset": {"version": "2.0", "generator": "swarmloc"},
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "terrain"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [
            {
                "pbrMetallicRoughness": {
                    "baseColorTexture": {"index": 0},
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0,
                },
                "doubleSided": True,
                "extensions": {"KHR_materials_unlit": {}},
            }
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": LINEAR, "minFilter": LINEAR}],
        "images": [{"bufferView": 3, "mimeType": "image/png"}],
        "buffers": [{"byteLength": buffer_bytes}],
        "bufferViews": views,
        "accessors": [
            {
                "bufferView": 0,
                "componentType": FLOAT,
                "count": 4,
                "type": "VEC3",
                "min": positions.min(axis=0).tolist(),
                "max": positions.max(axis=0).tolist(),
            },
            {"bufferView": 1, "componentType": FLOAT, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": UNSIGNED_SHORT, "count": 6, "type": "SCALAR"},
        ],
    }


def _padded(n: int) -> int:
    """``n`` rounded up to a multiple of 4 (GLB chunks and buffer views are 4-byte aligned)."""
    return (n + 3) // 4 * 4
