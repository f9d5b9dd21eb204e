"""Benchmarks, one module per ``pyopencl-rt bench`` subcommand (docs/BENCHMARKS.md):

* :mod:`.rays`: rays/s of the OpenCL traversal beside embreex, on :mod:`.workloads`' meshes and rays;
* :mod:`.bvh_build`: build time and SAH cost of the host BVH builder against the full sweep;
* :mod:`.render`: samples/s of the path tracer per device and intersector, on one scene or several,
  optionally in turns with Mitsuba 3 on the same scenes;
* :mod:`.bench_set`: the benchmark set against Mitsuba 3 (samples/s in turns, time to relMSE 1e-3
  against Mitsuba's best sampler, lanes) over :mod:`.render` and :mod:`.convergence`;
* :mod:`.materials`: the samples/s cost of textures, rough lobes and the glTF layer;
* :mod:`.convergence` (numbers in :mod:`.convergence_analysis`): error against render time;
* :mod:`.mitsuba_host`: Mitsuba 3 as the peer renderer, run in its own interpreter through the
  scripts :mod:`.mitsuba_runner` and :mod:`.mitsuba_cornell_box`, on scenes from :mod:`.mitsuba_export`.
* :mod:`.mitsuba_suite`: Mitsuba 3's render-regression scenes (a mitsuba-data checkout) judged
  by Mitsuba's own z-test.

:mod:`.timing` holds the timing rules they share (medians, alternating the variants compared).
"""
