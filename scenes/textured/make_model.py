"""Writes scenes/textured/model.glb (made for this project; licence: the project's).

A checker floor, a brick-textured box, a sphere whose metallic-roughness texture has metal and
rough bands, and an emissive panel with a striped emission texture (KHR_materials_emissive_strength),
all textures generated here.  Run: python scenes/textured/make_model.py
"""
import json
import struct
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from trimesh.visual import TextureVisuals
from trimesh.visual.material import PBRMaterial

N = 128


def checker():
    i, j = np.indices((N, N)) // 16
    a = np.where((i + j) % 2 == 0, 200, 60).astype(np.uint8)
    return Image.fromarray(np.stack([a, a, a], -1))


def bricks():
    y, x = np.indices((N, N))
    row = y // 16
    xs = (x + (row % 2) * 16) % 32
    mortar = (y % 16 < 2) | (xs < 2)
    rgb = np.where(mortar[..., None], [200, 195, 185], [150, 60, 40]).astype(np.uint8)
    return Image.fromarray(rgb)


def metal_rough():
    y, x = np.indices((N, N))
    band = (x // 32) % 2 == 0
    g = np.where(band, 60, 220)  # roughness: smooth / rough bands
    b = np.where(band, 255, 0)  # metallic: metal / plastic bands
    return Image.fromarray(np.stack([np.zeros_like(g), g, b], -1).astype(np.uint8))


def stripes():
    y, x = np.indices((N // 2, N // 2))
    a = np.where((x // 8) % 2 == 0, 255, 90).astype(np.uint8)
    return Image.fromarray(np.stack([a, a, a], -1))


def main(out=Path(__file__).with_name("model.glb")):
    sc = trimesh.Scene()
    floor = trimesh.Trimesh(vertices=[[-3, 0, -3], [3, 0, -3], [3, 0, 3], [-3, 0, 3]], faces=[[0, 2, 1], [0, 3, 2]],
                            process=False)
    floor.visual = TextureVisuals(uv=np.array([[0, 0], [3, 0], [3, 3], [0, 3]], float),
                                  material=PBRMaterial(name="floor", baseColorTexture=checker(), metallicFactor=0.0,
                                                       roughnessFactor=0.8))
    sc.add_geometry(floor, node_name="floor")

    box = trimesh.creation.box(extents=(1, 1, 1))
    box = trimesh.Trimesh(vertices=box.vertices[box.faces].reshape(-1, 3), faces=np.arange(36).reshape(-1, 3), process=False)
    axis = np.abs(box.face_normals).argmax(1).repeat(3)  # planar map per face: the other two axes
    other = np.array([[1, 2], [0, 2], [0, 1]])[axis]
    box_uv = np.take_along_axis(box.vertices, other, 1) + 0.5
    box.visual = TextureVisuals(uv=box_uv,
                                material=PBRMaterial(name="bricks", baseColorTexture=bricks(), metallicFactor=0.0,
                                                     roughnessFactor=1.0))
    sc.add_geometry(box, node_name="box", transform=trimesh.transformations.compose_matrix(
        angles=[0, 0.5, 0], translate=[-1.0, 0.5, 0.2]))

    ball = trimesh.creation.uv_sphere(radius=0.6, count=[24, 24])
    v = ball.vertices / 0.6
    uv = np.stack([0.5 + np.arctan2(v[:, 0], v[:, 2]) / (2 * np.pi), np.arccos(np.clip(v[:, 1], -1, 1)) / np.pi], -1)
    ball.visual = TextureVisuals(uv=uv, material=PBRMaterial(
        name="banded", baseColorFactor=[230, 180, 90, 255], metallicFactor=1.0, roughnessFactor=1.0,
        metallicRoughnessTexture=metal_rough()))
    sc.add_geometry(ball, node_name="ball", transform=trimesh.transformations.translation_matrix([1.0, 0.6, 0.0]))

    panel = trimesh.Trimesh(vertices=[[-1, 0, 0], [1, 0, 0], [1, 0.6, 0], [-1, 0.6, 0]], faces=[[0, 1, 2], [0, 2, 3]],
                            process=False)
    panel.visual = TextureVisuals(uv=np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float), material=PBRMaterial(
        name="lamp", baseColorFactor=[0, 0, 0, 255], emissiveFactor=[1.0, 0.9, 0.8], emissiveTexture=stripes(),
        metallicFactor=0.0))
    sc.add_geometry(panel, node_name="lamp", transform=trimesh.transformations.translation_matrix([0, 0.4, -2.0]))
    sc.export(out)
    add_material_extensions(out, {"lamp": {"KHR_materials_emissive_strength": {"emissiveStrength": 6.0}}})
    print(f"{out}: {out.stat().st_size} bytes")


def add_material_extensions(path, by_name):
    """Rewrite a GLB's JSON chunk, adding extensions to the materials named in by_name."""
    data = Path(path).read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + jlen])
    rest = data[20 + jlen:]
    used = set(tree.get("extensionsUsed", []))
    for m in tree.get("materials", []):
        for name, ext in by_name.items():
            if m.get("name") == name:
                m.setdefault("extensions", {}).update(ext)
                used.update(ext)
    tree["extensionsUsed"] = sorted(used)
    j = json.dumps(tree).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + rest
    Path(path).write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


if __name__ == "__main__":
    main()
