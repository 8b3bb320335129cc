"""examples/mitsuba/paper.py runs end to end (--all --tiny: 16x16 images at
4 spp, a few seconds): every material of examples/materials/paper/ loads,
every part writes its images and numbers, and the smooth clear slab's
furnace sphere, whose samples are all exactly 1, vanishes."""

import json
import os
import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("mitsuba")
pytest.importorskip("drjit")

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCRIPT = ROOT / "examples" / "mitsuba" / "paper.py"


def test_paper_script_renders_everything_tiny(tmp_path):
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    r = subprocess.run([sys.executable, str(SCRIPT), "--all", "--tiny", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    names = ["furnace_smooth_slab", "furnace_rough_slab", "materials", "top_bottom", "refl_trans", "thickness",
             "scattering", "microflake", "logo_drop", "equal_time", "approximations"]
    for n in names:
        assert (tmp_path / f"{n}.png").stat().st_size > 0, n
    furnace = {row["material"]: row for row in json.loads((tmp_path / "furnace.json").read_text())}
    assert abs(furnace["furnace_smooth_slab"]["sphere_mean"] - 1.0) < 1e-4
    table = json.loads((tmp_path / "table.json").read_text())
    assert {row["material"] for row in table} >= {"metal", "logo_drop", "diffuse_symbolic"}
