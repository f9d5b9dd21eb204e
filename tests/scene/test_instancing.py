"""Shape groups and instances (pyopencl_rt/scene/loaders/instancing.py): Mitsuba 3's shapegroup /
instance and pbrt-v4's ObjectBegin / ObjectInstance, checked against numpy (closed form): each
instance's copy of the group at instance to_world @ shape to_world, its normals by the inverse
transpose, its UVs kept, mirrored copies reversed, spheres kept or made ellipsoids, the Instance
records, and the errors and warnings Mitsuba's and pbrt's rules call for."""
from __future__ import annotations

import re

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError
from pyopencl_rt.scene.loaders.builder import sphere_mesh

import harness
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

OBJ = """v 0 0 0
v 1 0 0
v 0 1 0
vt 0 0
vt 1 0
vt 0.5 1
vn 0.3 0 1
vn 0 0.3 1
vn -0.2 -0.2 1
f 1/1/1 2/2/2 3/3/3
"""
ROT = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z


def _m(linear=np.eye(3), t=(0.0, 0.0, 0.0)):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = linear, t
    return m


SHAPE = _m(ROT * 0.5, (0.0, 0.0, 1.0))  # the mesh's own to_world in the group
INSTANCES = [_m(t=(1.0, 2.0, 3.0)),  # moved
             _m(np.diag([1.0, 2.0, 0.5]) @ ROT, (0.0, -1.0, 0.0)),  # rotated, scaled unevenly
             _m(np.diag([-2.0, 2.0, 2.0]), (4.0, 0.0, 0.0))]  # mirrored (a similarity)


def _matrix(m) -> str:
    return '<transform name="to_world"><matrix value="' + " ".join(f"{x:.17g}" for x in m.ravel()) + '"/></transform>'


def _xml(tmp_path, body, name="s.xml"):
    (tmp_path / "tri.obj").write_text(OBJ)
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">\n{body}\n</scene>\n')
    return path


GROUP = f"""<shape type="shapegroup" id="g">
  <shape type="obj"><string name="filename" value="tri.obj"/>{_matrix(SHAPE)}
    <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></shape>
  <shape type="sphere"><point name="center" x="0.5" y="0" z="0"/><float name="radius" value="0.25"/>
    <transform name="to_world"><scale value="2"/></transform></shape>
</shape>"""


def test_mitsuba_instances_closed_form(tmp_path):
    """Three instances of a group (an OBJ triangle with vertex normals and UVs under its own
    to_world, a sphere scaled by its own): vertices at M @ S @ v, normals M^-T times the group's
    unit normals normalize(S^-T n), up to one factor (not each made unit: an unevenly scaled
    instance interpolates them as Mitsuba does, in the group's space),
    UVs those of the same triangle loaded with to_world M S directly; the mirrored copy has its
    corners reversed; the sphere is a sphere (centre M (2 c), radius 0.5 |scale|) under the moving
    and the mirroring similarity and the ellipsoid's triangles under the uneven scale; the group
    alone draws nothing; one Instance record each."""
    body = GROUP + "".join(f'<shape type="instance"><ref id="g"/>{_matrix(m)}</shape>' for m in INSTANCES)
    scene, warned = harness.load_warned(_xml(tmp_path, body))
    assert warned == [] and scene.normals_as_given  # the uneven instance's normals keep their lengths
    n_ellipsoid = len(sphere_mesh(0.25)[1])
    assert len(scene.faces) == 3 + n_ellipsoid and len(sphere_of(scene.shapes)) == 2
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    n = np.array([[0.3, 0, 1], [0, 0.3, 1], [-0.2, -0.2, 1]])
    records = scene.instances
    assert [r.group for r in records] == ["g"] * 3
    assert [(r.n_faces, r.n_shapes) for r in records] == [(1, 1), (1 + n_ellipsoid, 0), (1, 1)]
    for k, (m, rec) in enumerate(zip(INSTANCES, records)):
        assert np.allclose(rec.to_world, m)
        full = m @ SHAPE
        want_v = v @ full[:3, :3].T + full[:3, 3]
        group_n = n @ np.linalg.inv(SHAPE[:3, :3])  # the group's (unit) normals, moved by M^-T
        want_n = (group_n / np.linalg.norm(group_n, axis=1, keepdims=True)) @ np.linalg.inv(m[:3, :3])
        order = [2, 1, 0] if np.linalg.det(m[:3, :3]) < 0 else [0, 1, 2]
        face = rec.first_face
        assert np.allclose(scene.vertices[scene.faces[face]], want_v[order], atol=1e-6), k
        # up to one factor: the kernels normalise the interpolation, which is then normalize(M^-T n(b))
        got = scene.normals[face].astype(np.float64)
        assert np.allclose(got / np.linalg.norm(got[0]), want_n[order] / np.linalg.norm(want_n[order][0]),
                           atol=1e-6), k
        direct, _ = harness.load_warned(_xml(tmp_path, f'<shape type="obj"><string name="filename" value="tri.obj"/>{_matrix(full)}'
                                         "</shape>", name=f"direct{k}.xml"))
        assert np.array_equal(scene.uvs[face], direct.uvs[0]), k
        assert np.allclose(scene.vertices[scene.faces[face]], direct.vertices[direct.faces[0]]), k
        assert scene.materials[scene.face_materials[face]].albedo == pytest.approx((0.2, 0.4, 0.6))
        if rec.n_shapes:
            centre = m[:3, :3] @ [1.0, 0.0, 0.0] + m[:3, 3]
            scale = abs(np.linalg.det(m[:3, :3])) ** (1 / 3)
            assert np.allclose(sphere_of(scene.shapes)[rec.first_shape], [*centre, 0.5 * scale], atol=1e-6), k
    # the ellipsoid: its triangles on M2 applied to the sphere of centre (1, 0, 0), radius 0.5
    m = INSTANCES[1]
    tris = scene.vertices[scene.faces[records[1].first_face + 1:records[1].first_face + 1 + n_ellipsoid]]
    local = (tris.reshape(-1, 3).astype(np.float64) - m[:3, 3]) @ np.linalg.inv(m[:3, :3]).T
    assert np.allclose(np.linalg.norm(local - [1.0, 0.0, 0.0], axis=1), 0.5, atol=1e-5)
    with pytest.raises(SceneError, match="the scene has no shapes that we can render"):
        harness.load_warned(_xml(tmp_path, GROUP, name="alone.xml"))


def test_mitsuba_instance_errors_and_emitters(tmp_path):
    """Mitsuba's rules: an instance needs one shapegroup and nothing else; no shapegroup or instance
    inside a shapegroup.  An area emitter in a group (which Mitsuba refuses) warns and emits from
    every instance."""
    cases = [
        ('<shape type="instance"/>', r':\d+: <shape type="instance">: needs a reference to a shapegroup'),
        ('<shape type="instance"><ref id="g"/><bsdf type="diffuse"/></shape>',
         r'<bsdf type="diffuse"> in <shape type="instance">: only a shapegroup can be specified'),
        ('<shape type="shapegroup" id="h"><shape type="instance"><ref id="g"/></shape></shape>',
         r"nested instancing is not permitted"),
        ('<shape type="shapegroup" id="h"><shape type="shapegroup" id="i"/></shape>',
         r"nested shapegroups are not permitted"),
    ]
    for k, (text, message) in enumerate(cases):
        with pytest.raises(SceneError) as info:
            harness.load_warned(_xml(tmp_path, GROUP + text + '<shape type="sphere"/>', name=f"bad{k}.xml"))
        assert "\n" not in str(info.value) and re.search(message, str(info.value)), (k, str(info.value))
    lit = ('<shape type="shapegroup" id="lamp"><shape type="rectangle"><emitter type="area">'
           '<rgb name="radiance" value="2"/></emitter></shape></shape>'
           '<shape type="instance"><ref id="lamp"/></shape>'
           '<shape type="instance"><ref id="lamp"/><transform name="to_world"><translate z="3"/></transform></shape>')
    scene, warned = harness.load_warned(_xml(tmp_path, lit, name="lamp.xml"))
    assert len(warned) == 1 and "instancing of emitters is not supported" in warned[0]
    assert len(scene.faces) == 4 and all(scene.materials[i].emission == (2.0, 2.0, 2.0) for i in scene.face_materials)


def test_pbrt_objects_share_the_instancing(tmp_path):
    """pbrt-v4's ObjectInstance through the same groups: a sphere under the object's own Scale 2
    keeps that scale (radius 2 r at the instance), an uneven instance scale makes it triangles; an
    AreaLightSource inside ObjectBegin warns and does not emit (pbrt-v4); an object defined twice is
    an error; one Instance record per ObjectInstance."""
    path = tmp_path / "s.pbrt"
    path.write_text('WorldBegin\nObjectBegin "o"\nAreaLightSource "diffuse"\nScale 2 2 2\n'
                    'Shape "sphere" "float radius" 0.5\nObjectEnd\n'
                    'AttributeBegin Translate 5 0 0 ObjectInstance "o" AttributeEnd\n'
                    'AttributeBegin Scale 1 1 3 ObjectInstance "o" AttributeEnd\n')
    scene, warned = harness.load_warned(path)
    assert len(warned) == 1 and "area lights are not supported with object instancing" in warned[0]
    assert np.allclose(sphere_of(scene.shapes), [[5.0, 0.0, 0.0, 1.0]])
    assert len(scene.faces) == len(sphere_mesh(0.5)[1]) and not any(m.is_emissive for m in scene.materials)
    z = scene.vertices[:, 2]
    assert z.max() == pytest.approx(3.0, rel=1e-5) and np.abs(scene.vertices[:, 0]).max() == pytest.approx(1.0, rel=1e-5)
    assert [(r.group, r.n_faces, r.n_shapes) for r in scene.instances] == [("o", 0, 1), ("o", len(scene.faces), 0)]
    path.write_text('WorldBegin\nObjectBegin "o"\nObjectEnd\nObjectBegin "o"\nObjectEnd\n')
    with pytest.raises(SceneError, match=r":4: ObjectBegin: object 'o' is already defined"):
        harness.load_warned(path)


@pytest.mark.parametrize("mode", ["two-level", "flatten"])
def test_framing_camera_sees_the_instances_in_the_world(tmp_path, monkeypatch, mode):
    """A file without a sensor is framed around its world-space geometry: a two-level scene
    (its group's faces kept in the group's space, near the origin) gets the camera of the same
    file flattened, around the instances (moved far along +x and up, turned, scaled unevenly) and
    the world quad; not a box that holds the group's own-space vertices."""
    from pyopencl_rt.scene.loaders import load_scene
    from pyopencl_rt.scene.loaders.instancing import INSTANCING_ENV

    group = (f'<shape type="shapegroup" id="m"><shape type="obj"><string name="filename" value="tri.obj"/>'
             f'{_matrix(SHAPE)}<bsdf type="diffuse"/></shape></shape>')
    moves = [_m(ROT * 2.0, (40.0, 0.0, 0.0)), _m(np.diag([1.0, 3.0, 1.0]), (60.0, 10.0, -5.0))]
    body = group + "".join(f'<shape type="instance"><ref id="m"/>{_matrix(m)}</shape>' for m in moves)
    body += ('<shape type="rectangle"><transform name="to_world"><translate x="30" z="-2"/></transform>'
             '<bsdf type="diffuse"/></shape>')
    path = _xml(tmp_path, body)
    monkeypatch.setenv(INSTANCING_ENV, "flatten")
    flat = load_scene(path)
    monkeypatch.setenv(INSTANCING_ENV, mode)
    scene = load_scene(path)
    assert bool(scene.blas_groups) == (mode == "two-level")
    assert np.allclose(scene.camera.eye, flat.camera.eye) and np.allclose(scene.camera.look_at, flat.camera.look_at)
    # the flattened copies' box: every moved corner of the group, and the quad
    v = np.asarray(flat.vertices, np.float64)[np.unique(flat.faces)]
    assert np.allclose(flat.camera.look_at, (v.min(0) + v.max(0)) / 2, atol=1e-4)
    assert 30 < flat.camera.look_at[0] < 50


def _big_ply(path, k=370):
    """A flat k x k grid of (k - 1)^2 * 2 triangles (> 2^18 for k = 370) as a binary PLY."""
    x, y = np.meshgrid(np.arange(k, dtype=np.float32), np.arange(k, dtype=np.float32))
    v = np.stack([x.ravel(), y.ravel(), np.zeros(k * k, np.float32)], 1)
    i = np.arange(k * k).reshape(k, k)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int32)
    rec = np.zeros(len(f), [("n", "u1"), ("i", "<i4", 3)])
    rec["n"], rec["i"] = 3, f
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    path.write_bytes(head.encode() + v.astype("<f4").tobytes() + rec.tobytes())
    return len(f)


@pytest.mark.parametrize("instances", [1, 2])
def test_auto_draws_a_group_instanced_once_flattened(tmp_path, monkeypatch, instances):
    """auto: a group of more than FLATTEN_MAX_TRIANGLES drawn once is flattened (its own space would
    save nothing, and pbrt exporters wrap single meshes in ObjectBegin / ObjectInstance: kroken's 54M-
    triangle displaced carpet was refused as an instanced BVH over 2 GiB); drawn twice, two-level."""
    from pyopencl_rt.scene.loaders import load_scene
    from pyopencl_rt.scene.loaders.instancing import FLATTEN_MAX_TRIANGLES, INSTANCING_ENV

    n = _big_ply(tmp_path / "big.ply")
    assert n > FLATTEN_MAX_TRIANGLES
    uses = "".join(f"AttributeBegin\nTranslate {500 * k} 0 0\nObjectInstance \"g\"\nAttributeEnd\n" for k in range(instances))
    (tmp_path / "s.pbrt").write_text('LookAt 0 0 -900  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
                                     'ObjectBegin "g"\nShape "plymesh" "string filename" "big.ply"\nObjectEnd\n' + uses)
    monkeypatch.setenv(INSTANCING_ENV, "auto")
    scene = load_scene(tmp_path / "s.pbrt")
    assert bool(scene.blas_groups) == (instances == 2)
    assert len(scene.faces) == n * (1 if instances == 2 else instances)  # two-level: the group's faces once
