"""scripts/curl_stats.py: the curl measured from strands' tangents gives back the radius, period and pitch
angle of helices; straight strands have none; a missing file is an error."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import _hairio as hio

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import curl_stats  # noqa: E402

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "curl_stats.py"


def _helices(tmp_path: Path, radius: float, period: float, n: int = 40) -> Path:
    """``n`` helices about axes that lean by different angles, at random phases, 250 mm of axis each,
    3,000 points (finer than the script's 0.5 mm resampling)."""
    rng = np.random.default_rng(3)
    pts, counts = [], []
    z = np.linspace(0.0, 0.25, 3000)
    for _ in range(n):
        phi = rng.uniform(0, 2 * np.pi) + 2 * np.pi * z / period
        local = np.stack([radius * np.cos(phi), radius * np.sin(phi), -z], 1)
        a = rng.uniform(0, 0.8)  # tilt of the axis about x
        rot = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        pts.append(local @ rot.T + rng.uniform(-0.1, 0.1, 3))
        counts.append(len(z))
    path = tmp_path / f"helix_{radius}_{period}.hair"
    hio.write_hair(path, np.concatenate(pts).astype(np.float32), np.array(counts))
    return path


@pytest.mark.parametrize("radius,period", [(0.0065, 0.022), (0.009, 0.022), (0.004, 0.015)])
def test_the_helices_curl_comes_back(tmp_path, radius, period):
    c = curl_stats.curl_stats(_helices(tmp_path, radius, period))["curl"]
    arc = np.hypot(period, 2 * np.pi * radius)
    assert c["arc_per_turn"] == pytest.approx(arc, rel=0.01)
    assert c["radius"] == pytest.approx(radius, rel=0.03)
    assert c["period"] == pytest.approx(period, rel=0.03)
    assert c["pitch_deg"] == pytest.approx(np.degrees(np.arctan2(2 * np.pi * radius, period)), abs=1.0)


def test_the_autocorrelation_of_a_helix_follows_the_formula():
    # C(Δ) = cos²ψ + sin²ψ cos(2πΔ/L) sampled, then read back.
    psi, arc, step = np.radians(61.7), 0.0464, 0.0005
    lags = np.arange(0, 0.12, step)
    c = np.cos(psi) ** 2 + np.sin(psi) ** 2 * np.cos(2 * np.pi * lags / arc)
    got = curl_stats.curl_from_autocorrelation(c, step)
    assert got["arc_per_turn"] == pytest.approx(arc, rel=1e-3)
    assert got["pitch_deg"] == pytest.approx(61.7, abs=0.05)
    assert got["c_min"] == pytest.approx(np.cos(2 * psi), abs=1e-3)


def test_straight_strands_have_no_curl(tmp_path):
    z = np.linspace(0.0, 0.3, 300)
    pts = np.concatenate([np.stack([np.full_like(z, x), 0.01 * np.sin(z), -z], 1) for x in (0.0, 0.01, 0.02)])
    path = tmp_path / "straight.hair"
    hio.write_hair(path, pts.astype(np.float32), np.array([300, 300, 300]))
    assert curl_stats.curl_stats(path)["curl"] is None
    out = subprocess.run([sys.executable, str(SCRIPT), str(path)], capture_output=True, text=True)
    assert out.returncode == 0 and "no curl" in out.stdout


def test_a_missing_or_bad_file_is_named(tmp_path):
    out = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / "none.hair")], capture_output=True, text=True)
    assert out.returncode == 2 and "none.hair" in out.stderr
    bad = tmp_path / "bad.hair"
    bad.write_bytes(b"not hair")
    out = subprocess.run([sys.executable, str(SCRIPT), str(bad)], capture_output=True, text=True)
    assert out.returncode == 2 and "not a .hair file" in out.stderr


@pytest.mark.parametrize("curl,radius,period", [(None, 0.0065, 0.022), ("4.5,16", 0.0045, 0.016)])
def test_synth_hair_makes_the_curl_asked_for(tmp_path, curl, radius, period):
    """``hairrecon synth-hair --style curly [--curl R,P]``: the generated strands have that curl, as
    their tangents measure it (clumping and the root ramp bend them: measured 6.2 / 22.9 mm for the
    preset's 6.5 / 22, 4.3 / 16.8 mm for 4.5 / 16), and a malformed --curl is refused by name."""
    from conftest import hairrecon_bin

    exe, out = hairrecon_bin(), tmp_path / "curly.hair"
    cmd = [str(exe), "synth-hair", "--style", "curly", "--strands", "1500", "--out", str(out)]
    cmd += ["--curl", curl] if curl else []
    subprocess.run(cmd, check=True, capture_output=True)
    got = curl_stats.curl_stats(out)["curl"]
    assert got["radius"] == pytest.approx(radius, rel=0.10)
    assert got["period"] == pytest.approx(period, rel=0.10)
    bad = subprocess.run([str(exe), "synth-hair", "--style", "curly", "--curl", "4.5", "--out", str(tmp_path / "x.hair")],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and "RADIUS_MM,PERIOD_MM" in bad.stderr
    assert not (tmp_path / "x.hair").exists()
