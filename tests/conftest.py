"""Shared fixtures: every device test runs on each available OpenCL device.

Select devices with ``PYOPENCL_TEST`` (comma-separated specs as for ``--device``, e.g.
``PYOPENCL_TEST=cpu`` or ``PYOPENCL_TEST=0:0,1:0``); by default every device found is used.
"""
import numpy as np
import pytest

from pyopencl_rt.device import devices as dv


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        specs = dv.device_test_specs()
        metafunc.parametrize("device", specs, ids=[f"dev{s}" for s in specs], indirect=True)


@pytest.fixture
def device(request):
    return dv.select_device(request.param)


@pytest.fixture
def runtime(device):
    from pyopencl_rt.device.kernels import runtime as rt

    return rt(device)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
