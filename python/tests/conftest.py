"""Shared fixtures of the rephoto Python tests (run by scripts/test.sh through pytest)."""
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def cli_path() -> str:
    """The rephoto CLI built beside the package: $REPHOTO_CLI, else build/apps/rephoto/rephoto."""
    path = os.environ.get("REPHOTO_CLI", str(ROOT / "build" / "apps" / "rephoto" / "rephoto"))
    if not os.path.exists(path):
        found = shutil.which("rephoto")
        if not found:
            pytest.skip(f"rephoto CLI not found at {path} (set REPHOTO_CLI)")
        path = found
    return path


@pytest.fixture
def cli():
    def run(*args, check=True):
        return subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True,
                              check=check)
    return run


def write_png(path, array):
    from skimage import io
    io.imsave(str(path), array, check_contrast=False)


@pytest.fixture
def pair():
    """A 8-bit photo (values 1..254, no ill-exposed pixel) and a noisy rendering of it."""
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:67, 0:91]
    base = np.stack([np.sin(x / 7.0), np.cos(y / 5.0), np.sin((x + y) / 11.0)], axis=2)
    photo = np.clip(np.round(127 + 100 * base + rng.normal(0, 10, base.shape)), 1, 254)
    render = np.clip(np.round(photo + rng.normal(0, 12, base.shape)), 1, 254)
    return photo.astype(np.uint8), render.astype(np.uint8)
