"""Shared fixtures: the workspace root and the `vgps` command-line binary built beside the
wheel (target/release/vgps), to compare Python's answers with the command line's."""

import os
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def vgps_cli() -> str:
    """The release CLI binary (VGPS_CLI overrides); tests comparing with it are skipped
    without one."""
    path = os.environ.get("VGPS_CLI") or str(ROOT / "target" / "release" / "vgps")
    if not (os.path.exists(path) or shutil.which(path)):
        pytest.skip(f"no vgps command-line binary at {path}")
    return path
