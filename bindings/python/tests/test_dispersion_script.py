"""examples/mitsuba/dispersion.py runs end to end (--tiny: 32x32 at 4 spp in
llvm_ad_spectral): the dispersive prism and its fixed-IOR twin render and the
script writes its image and numbers."""

import json
import os
import pathlib
import subprocess
import sys

import pytest

mi = pytest.importorskip("mitsuba")

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCRIPT = ROOT / "examples" / "mitsuba" / "dispersion.py"


def test_dispersion_script_renders_tiny(tmp_path):
    if "llvm_ad_spectral" not in mi.variants():
        pytest.skip("Mitsuba variant llvm_ad_spectral not available")
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    r = subprocess.run([sys.executable, str(SCRIPT), "--tiny", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    assert (tmp_path / "dispersion.png").stat().st_size > 0
    report = json.loads((tmp_path / "dispersion.json").read_text())
    assert report["size"] == 32 and report["variant"] == "llvm_ad_spectral"
    assert {"dispersive", "ior fixed at nd"} <= report.keys()
