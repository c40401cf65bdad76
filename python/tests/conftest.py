"""Fixtures of the Python package's tests: the `plume` binary beside it (for the command
line's images) and a small generated explosion."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def plume_bin() -> str:
    """The command-line binary: $PLUME_BIN (scripts/test.sh sets it), else the build's."""
    path = os.environ.get("PLUME_BIN") or str(ROOT / "target" / "debug" / "plume")
    if not os.access(path, os.X_OK):
        pytest.fail(f"no plume binary at {path}: build it (cargo build) or set PLUME_BIN")
    return path


@pytest.fixture(scope="session")
def explosion(tmp_path_factory, plume_bin) -> pathlib.Path:
    """A generated 32³ explosion (density + temperature) as a .vdb."""
    path = tmp_path_factory.mktemp("data") / "explosion.vdb"
    subprocess.run(
        [plume_bin, "synth", "explosion", "--resolution", "32", "--seed", "2", "-o", str(path)],
        check=True,
        capture_output=True,
    )
    return path


def shared(relative: str) -> pathlib.Path:
    """A file of the shared real data beside the checkout (../shared/data)."""
    return ROOT.parent / "shared" / "data" / relative
