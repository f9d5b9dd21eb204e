"""Mitsuba 3's ``sdfgrid`` shape (pyopencl_rt/scene/loaders/sdfgrid.py): the zero level set of a
signed distance grid as triangles, against the closed form of the sphere it samples and against
Mitsuba's own render of the same file."""
from __future__ import annotations

import struct

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.scene.loaders.sdfgrid import sdf_mesh, trilinear

import harness


def grid(fn, n):
    """The values of ``fn`` (points (..., 3) -> distances) at the n^3 corners of the unit cube's cells, as
    Mitsuba stores them: (z, y, x)."""
    p = np.stack(np.meshgrid(*[np.linspace(0.0, 1.0, n)] * 3, indexing="ij"), -1)  # (x, y, z, 3)
    return fn(p).transpose(2, 1, 0)


def sphere_sdf(c, r):
    return lambda p: np.linalg.norm(p - c, axis=-1) - r


def torus_sdf(c, big, small):
    def fn(p):
        q = p - c
        return np.hypot(np.hypot(q[..., 0], q[..., 2]) - big, q[..., 1]) - small
    return fn


def write_vol(path, values):
    """A Mitsuba .vol (version 3, float32, one channel) of (z, y, x) values over the unit cube."""
    nz, ny, nx = values.shape
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]) + struct.pack("<i3ii6f", 1, nx, ny, nz, 1, 0, 0, 0, 1, 1, 1))
        f.write(np.ascontiguousarray(values, np.float32).tobytes())
    return str(path)


def test_the_mesh_of_a_sphere_grid():
    """A 24^3 grid of a sphere's distances (radius 0.3, cells 1/23): a closed surface (every edge in
    two triangles), every triangle facing outwards, its vertices within 0.06 of a cell of the sphere
    (the trilinear field's deviation from the distance), its area within 1% of 4 pi r^2, its
    shading normals (the field's gradient) within 0.1 of the sphere's normal; the trilinear field
    itself is the grid at the corners."""
    c, r, n = np.array([0.5, 0.45, 0.55]), 0.3, 24
    values = grid(sphere_sdf(c, r), n)
    v, f, normals = sdf_mesh(values)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), 1)
    assert (np.unique(edges, axis=0, return_counts=True)[1] == 2).all()
    tri = v[f]
    area_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (np.einsum("ij,ij->i", area_n, tri.mean(1) - c) > 0).all()
    assert np.abs(np.linalg.norm(v - c, axis=1) - r).max() < 0.06 / (n - 1)
    assert np.isclose(0.5 * np.linalg.norm(area_n, axis=1).sum(), 4 * np.pi * r * r, rtol=0.01)
    exact = (tri - c) / np.linalg.norm(tri - c, axis=-1, keepdims=True)
    assert np.abs(normals - exact).max() < 0.1
    corners = np.array([[0, 0, 0], [1, 11 / 23, 5 / 23], [7 / 23, 11 / 23, 1]])
    value, _ = trilinear(values, corners)
    assert np.allclose(value, sphere_sdf(c, r)(corners), atol=1e-12)


SENSOR = harness.mitsuba_sensor("0.5, 1.6, 3.0", 30, 64, 48, max_depth=3, spp=32, target="0.5, 0.45, 0.5")


def test_sdfgrids_as_mitsubas(tmp_path):
    """A sphere and a torus from .vol grids of their distances (24^3 and 32^3), the torus moved by
    its to_world, under a point light and a constant sky, against Mitsuba's render of the same file
    (8 batches of 32 spp; ours 256): every 8 x 8 tile within 4.5 sigma (measured: 2.9, the mean
    1.001 of Mitsuba's; 6.7 with each cell meshed whole, sdfgrid.REFINE_CELLS).  Without the torus
    some tile is more than 10 sigma off (measured: 167)."""
    sphere = write_vol(tmp_path / "sphere.vol", grid(sphere_sdf(np.array([0.5, 0.5, 0.5]), 0.35), 24))
    torus = write_vol(tmp_path / "torus.vol", grid(torus_sdf(np.array([0.5, 0.5, 0.5]), 0.3, 0.12), 32))
    body = f"""{SENSOR}
<emitter type="point"><point name="position" x="1.5" y="2.5" z="2"/><rgb name="intensity" value="6"/></emitter>
<emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>
<shape type="sdfgrid"><string name="filename" value="{sphere}"/>
  <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf>
  <transform name="to_world"><translate x="-0.1" z="-0.2"/></transform></shape>
<shape type="sdfgrid"><string name="filename" value="{torus}"/><string name="normals" value="analytic"/>
  <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.7"/></bsdf>
  <transform name="to_world"><scale value="0.8"/><translate x="0.65" y="0.1" z="0.3"/></transform></shape>
<shape type="rectangle"><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  <transform name="to_world"><scale value="3"/><rotate x="1" angle="-90"/><translate y="0.1"/></transform></shape>
"""
    path = harness.write_mitsuba_scene(tmp_path / "sdf.xml", body)
    z, _ours, _var, theirs, their_var = harness.against_mitsuba(harness.mitsuba(), path, seed=2)
    assert z.max() < 4.5, np.round(z.max(-1), 1)
    no_torus = harness.write_mitsuba_scene(tmp_path / "no_torus.xml", body.replace(torus, sphere).replace(
        '<scale value="0.8"/><translate x="0.65" y="0.1" z="0.3"/>', '<translate x="9"/>'))
    other = rt.render_full(load_scene(no_torus), spp=256, device="cpu", seed=2)
    assert harness.tile_z(other.image.astype(np.float64), other.film.variance_of_mean(), theirs, their_var).max() > 10


def test_what_an_sdfgrid_cannot_be_is_one_line(tmp_path):
    """As an area emitter (Mitsuba refuses it too), with three channels, without a zero crossing."""
    good = write_vol(tmp_path / "g.vol", grid(sphere_sdf(np.array([0.5, 0.5, 0.5]), 0.3), 8))
    empty = write_vol(tmp_path / "e.vol", np.ones((4, 4, 4)))
    three = tmp_path / "c.vol"
    three.write_bytes(b"VOL" + bytes([3]) + struct.pack("<i3ii6f", 1, 2, 2, 2, 3, 0, 0, 0, 1, 1, 1)
                      + np.zeros(24, np.float32).tobytes())
    cases = (
        (f'<shape type="sdfgrid"><string name="filename" value="{good}"/><emitter type="area"/></shape>', "emitter"),
        (f'<shape type="sdfgrid"><string name="filename" value="{three}"/></shape>', "channels"),
        (f'<shape type="sdfgrid"><string name="filename" value="{empty}"/></shape>', "no zero crossing"),
    )
    for body, needle in cases:
        path = harness.write_mitsuba_scene(tmp_path / "bad.xml", body)
        with pytest.raises(UserError) as caught:
            load_scene(path)
        assert "\n" not in str(caught.value) and needle in str(caught.value), str(caught.value)
