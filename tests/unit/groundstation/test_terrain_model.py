"""The terrain model under a camera swarm: a valid binary glTF (header, JSON and BIN chunks, 4-byte
aligned), one quad whose corners lie where the image's corners are in the world (the 3-D panel turns
glTF's Y-up into Z-up: world (x, y) is glTF (x, 0, -y)) with the image's top left at the north-west
corner, and the image itself as the PNG texture."""

import json
import struct

import cv2
import numpy as np

from groundstation.terrain_model import CHUNK_BIN, CHUNK_JSON, GLB_MAGIC, MAX_TEXTURE_PX, terrain_glb


def _chunks(glb: bytes) -> tuple[dict, bytes]:
    magic, version, total = struct.unpack_from("<III", glb, 0)
    assert (magic, version, total) == (GLB_MAGIC, 2, len(glb))
    json_length, json_type = struct.unpack_from("<II", glb, 12)
    assert json_type == CHUNK_JSON and json_length % 4 == 0
    document = json.loads(glb[20 : 20 + json_length])
    bin_length, bin_type = struct.unpack_from("<II", glb, 20 + json_length)
    assert bin_type == CHUNK_BIN and bin_length % 4 == 0 and 28 + json_length + bin_length == len(glb)
    return document, glb[28 + json_length :]


def _accessor(document: dict, binary: bytes, index: int, dtype: str, width: int) -> np.ndarray:
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    assert view["byteOffset"] % 4 == 0
    raw = binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
    return np.frombuffer(raw, dtype=dtype).reshape(accessor["count"], width)


def _texture(binary: bytes, view: dict) -> np.ndarray:
    png = np.frombuffer(binary, np.uint8, view["byteLength"], view["byteOffset"])
    return cv2.imdecode(png, cv2.IMREAD_UNCHANGED)


def test_the_terrain_is_a_glb_quad_on_the_ground_with_the_image_as_texture():
    rng = np.random.default_rng(1)
    image = rng.integers(0, 255, size=(300, 200), dtype=np.uint8)
    image[:10, :10] = 255  # a white north-west corner
    document, binary = _chunks(terrain_glb(image, width_m=20.0, height_m=30.0))
    primitive = document["meshes"][0]["primitives"][0]
    corners = _accessor(document, binary, primitive["attributes"]["POSITION"], "<f4", 3)
    uvs = _accessor(document, binary, primitive["attributes"]["TEXCOORD_0"], "<f4", 2)
    world = np.stack([corners[:, 0], -corners[:, 2]], axis=1)  # glTF (x, 0, -y) -> world (x, y)
    assert np.all(corners[:, 1] == 0.0)
    assert sorted(map(tuple, world.tolist())) == [(-10, -15), (-10, 15), (10, -15), (10, 15)]
    north_west = np.flatnonzero((world[:, 0] < 0) & (world[:, 1] > 0))[0]
    assert tuple(uvs[north_west]) == (0.0, 0.0)  # the image's top left
    indices = _accessor(document, binary, primitive["indices"], "<u2", 1).ravel()
    assert sorted(set(indices.tolist())) == [0, 1, 2, 3] and len(indices) == 6
    picture = document["images"][0]
    view = document["bufferViews"][picture["bufferView"]]
    texture = _texture(binary, view)
    assert picture["mimeType"] == "image/png" and np.array_equal(texture, image)
    assert document["materials"][0]["extensions"] == {"KHR_materials_unlit": {}}


def test_a_large_terrain_is_scaled_down_to_a_texture_a_viewer_loads():
    image = np.zeros((4096, 2048), np.uint8)
    document, binary = _chunks(terrain_glb(image, width_m=204.8, height_m=409.6))
    view = document["bufferViews"][document["images"][0]["bufferView"]]
    texture = _texture(binary, view)
    assert texture.shape == (MAX_TEXTURE_PX, MAX_TEXTURE_PX // 2)
