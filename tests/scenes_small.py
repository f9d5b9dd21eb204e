"""A small scene built in code, for the multi-device, checkpoint and Dask tests: a diffuse floor
and a ball under an emissive sky sphere (every path does something; 48 x 32 pixels)."""
import numpy as np

from pyopencl_rt.scene.model import Camera, Material, RenderSettings, Scene
from pyopencl_rt.scene.shapes.sphere import records as sphere_records


def small_scene(width=48, height=32, seed=7, max_depth=4, ball=(0.3, 0.6, 0.8)):
    v = np.array([[-50, 0, -50], [50, 0, -50], [50, 0, 50], [-50, 0, 50]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    mats = [Material("floor", albedo=(0.6, 0.5, 0.4)), Material("ball", albedo=ball),
            Material("sky", albedo=(0, 0, 0), emission=(1.5, 1.5, 1.5), two_sided=True)]
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32), materials=mats,
                 camera=Camera(eye=(0, 2, 6), look_at=(0, 0.8, 0), up=(0, 1, 0), fov=45),
                 shapes=sphere_records(np.array([[0, 1, 0, 1], [0, 0, 0, 1000]], np.float32)),
                 shape_materials=np.array([1, 2], np.int32),
                 settings=RenderSettings(width=width, height=height, max_depth=max_depth, seed=seed, spp=8))


def shading_scene(width=40, height=30, seed=3, max_depth=5):
    """Shading normals, normal and bump maps and vertex colours (cl/scene/shading.h), on every
    material type, beside flat faces and an analytic sphere: a floor; a diffuse ball with smooth
    normals and vertex colours (its lower half flat: zero normals); a rough glTF ball with a normal
    map under Mitsuba's rules; a rough gold ball with a bump map; a glass ball with smooth normals
    and a normal map under no rule (pbrt's and glTF's); a lamp, a point and a directional light."""
    from pyopencl_rt.scene.loaders.builder import SceneBuilder, quad_mesh, sphere_mesh
    from pyopencl_rt.scene.model import DirectionalLight, MITSUBA_MAP, PointLight
    from pyopencl_rt.scene.textures import texture_from_array

    y, x = np.mgrid[0:16, 0:16] / 16.0
    bumps = np.stack([0.5 + 0.35 * np.sin(2 * np.pi * 3 * x), 0.5 + 0.35 * np.cos(2 * np.pi * 2 * y),
                      np.full_like(x, 0.8)], -1).astype(np.float32)
    height_map = (0.5 + 0.5 * np.sin(2 * np.pi * 4 * x) * np.sin(2 * np.pi * 3 * y)).astype(np.float32)
    normal_map = texture_from_array(bumps, name="bumps")
    b = SceneBuilder("shading", "test")
    qv, qf, quv = quad_mesh([(-4, 0, -4), (-4, 0, 4), (4, 0, 4), (4, 0, -4)])
    b.add_mesh(qv, qf, Material("floor", albedo=(0.6, 0.6, 0.5)), uvs=quv)
    v, f, uv = sphere_mesh(0.6, n_theta=10)
    smooth = (v / 0.6)[f].astype(np.float32)
    lower = v[f][:, :, 2].mean(axis=1) < 0
    flat_lower = np.where(lower[:, None, None], 0.0, smooth).astype(np.float32)
    colors = (0.5 + 0.5 * (v / 0.6))[f].astype(np.float32)
    up = np.array([[1, 0, 0, 0], [0, 0, 1, 0.6], [0, -1, 0, 0], [0, 0, 0, 1]], np.float64)  # z up -> y up

    def at(x0, z0):
        m = up.copy()
        m[0, 3], m[2, 3] = x0, z0
        return m

    b.add_mesh(v, f, Material("colored", albedo=(1.0, 1.0, 1.0), vertex_colors=True), uvs=uv, matrix=at(-1.4, 0),
               normals=flat_lower, colors=colors)
    b.add_mesh(v, f, Material("mapped", type="gltf", albedo=(0.7, 0.3, 0.2), metallic=0.2, alpha=0.16,
                              normal_texture=normal_map, map_conventions=MITSUBA_MAP), uvs=uv, matrix=at(0, 0),
               normals=smooth)
    b.add_mesh(v, f, Material("bumped", type="conductor", eta=(0.18, 0.42, 1.37), k=(3.42, 2.35, 1.77), alpha=0.09,
                              alpha_v=0.3, distribution="beckmann", masking="separable",
                              normal_texture=texture_from_array(height_map, name="height"), bump_map=True,
                              normal_scale=0.05, map_conventions=MITSUBA_MAP), uvs=uv, matrix=at(1.4, 0),
               normals=smooth)
    b.add_mesh(v, f, Material("glass", type="dielectric", ior=1.5, normal_texture=normal_map, normal_scale=0.5,
                              alpha=0.2, alpha_v=0.04),
               uvs=uv, matrix=at(0.7, 1.3), normals=smooth)
    b.add_sphere((-1.5, 2.4, 1.5), 0.3, Material("lamp", albedo=(0, 0, 0), emission=(6.0, 5.0, 4.0)))
    b.add_light(PointLight(position=(1.0, 2.5, 2.0), intensity=(3.0, 3.0, 3.0)))
    b.add_light(DirectionalLight(direction=(0.3, -1.0, -0.4), irradiance=(0.6, 0.6, 0.6)))
    b.camera = Camera(eye=(0, 1.6, 4.5), look_at=(0, 0.5, 0), up=(0, 1, 0), fov=45)
    b.settings = RenderSettings(width=width, height=height, seed=seed, max_depth=max_depth, spp=4)
    return b.build()
