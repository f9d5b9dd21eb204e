"""A small scene built in code, for the multi-device, checkpoint and Dask tests: a diffuse floor
and a ball under an emissive sky sphere (every path does something; 48 x 32 pixels)."""
import numpy as np

from pyopencl_rt.scene.model import Camera, Material, RenderSettings, Scene


def small_scene(width=48, height=32, seed=7, max_depth=4, ball=(0.3, 0.6, 0.8)):
    v = np.array([[-50, 0, -50], [50, 0, -50], [50, 0, 50], [-50, 0, 50]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    mats = [Material("floor", albedo=(0.6, 0.5, 0.4)), Material("ball", albedo=ball),
            Material("sky", albedo=(0, 0, 0), emission=(1.5, 1.5, 1.5), two_sided=True)]
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32), materials=mats,
                 camera=Camera(eye=(0, 2, 6), look_at=(0, 0.8, 0), up=(0, 1, 0), fov=45),
                 spheres=np.array([[0, 1, 0, 1], [0, 0, 0, 1000]], np.float32),
                 sphere_materials=np.array([1, 2], np.int32),
                 settings=RenderSettings(width=width, height=height, max_depth=max_depth, seed=seed, spp=8))
