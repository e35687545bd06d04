"""Shared test set-up: quiet Warp, the devices to test on (the CPU, and CUDA where present)."""
import os

import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING
os.environ.setdefault("TQDM_DISABLE", "1")

DEVICES = ["cpu"] + (["cuda"] if wp.get_cuda_device_count() > 0 else [])


@pytest.fixture(params=DEVICES)
def device(request):
    """Each available device in turn: physics tests run the same code on the CPU and on CUDA."""
    return request.param
