"""Acceleration structures: the SAH BVH builder (:mod:`.bvh`; its binned build is compiled in
:mod:`.bvh_binned`), the 4-wide CPU layout (:mod:`.bvh_wide`), the per-device node buffers
(:mod:`.device_bvh`) and Embree as the reference (:mod:`.embree`).
"""
