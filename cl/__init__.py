# OpenCL C kernel sources.  This file only makes cl/ installable as the package data
# ``pyopencl_rt.cl``; pyopencl_rt.kernels finds the sources both here (source checkout,
# editable install) and inside an installed wheel.
