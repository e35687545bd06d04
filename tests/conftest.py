"""Shared test set-up: quiet Warp, the devices to test on (the CPU, and CUDA where present)."""
import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING

DEVICES = ["cpu"] + (["cuda"] if wp.get_cuda_device_count() > 0 else [])


@pytest.fixture(params=DEVICES)
def device(request):
    """Each available device in turn: physics tests run the same code on the CPU and on CUDA."""
    return request.param
