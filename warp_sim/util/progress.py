"""The progress bar of runs and sweeps: tqdm's notebook bar inside Jupyter, its text bar elsewhere.

``tqdm.autonotebook`` without its experimental-mode warning: what ``tqdm.auto`` gives, less its asyncio
support, whose import (asyncio, then ssl) cost about 0.1 s of every ``import warp_sim``.
"""
from __future__ import annotations

import warnings

from tqdm.std import TqdmExperimentalWarning

with warnings.catch_warnings():
    warnings.simplefilter("ignore", category=TqdmExperimentalWarning)
    from tqdm.autonotebook import tqdm

__all__ = ["tqdm"]
