"""Shared test set-up: quiet Warp, the devices to test on (the CPU, and CUDA where present)."""
import pytest
import warp as wp

from warp_sim.core import compiling

wp.config.log_level = wp.LOG_WARNING
compiling.set_notices(False)   # a cold cache's "compiling kernels" line would add to the stderr tests count

DEVICES = ["cpu"] + (["cuda"] if wp.get_cuda_device_count() > 0 else [])


@pytest.fixture(params=DEVICES)
def device(request):
    """Each available device in turn: physics tests run the same code on the CPU and on CUDA."""
    return request.param
