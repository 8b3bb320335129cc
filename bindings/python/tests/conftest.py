"""Shared fixtures: the repository root, the example materials and the CLI."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]
MATERIALS = ROOT / "examples" / "materials"


def cli_path():
    """The `strata` binary: $STRATA_CLI, else the release build of the workspace."""
    env = os.environ.get("STRATA_CLI")
    if env:
        return pathlib.Path(env)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for p in (target / "release" / "strata", ROOT / "target" / "release" / "strata"):
        if p.exists():
            return p
    found = shutil.which("strata")
    return pathlib.Path(found) if found else None


@pytest.fixture(scope="session")
def strata_cli():
    p = cli_path()
    if p is None or not p.exists():
        pytest.fail("the strata CLI is needed: cargo build --release -p strata-cli (or set STRATA_CLI)")
    return p


@pytest.fixture(scope="session")
def materials():
    return MATERIALS
