"""hairrecon.fit_head on a capture as an import leaves it (tests/python/fit_fixture.py: the bundled head
moved by a similarity as the raw mesh, four cameras, no scalp): the frame is recovered, the fitted
scalp lies on the true one in the capture's frame, write=True adds the fitted meshes to the capture;
a sphere does not fit and says so.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

hairrecon = pytest.importorskip("hairrecon")

from fit_fixture import OFFSET, ROTATION, SCALE, to_capture, write_capture  # noqa: E402


def test_fit_head_recovers_the_frame_and_the_scalp(tmp_path):
    cap = tmp_path / "cap"
    truth = write_capture(hairrecon, cap)
    fit = hairrecon.fit_head(str(cap))
    frame = fit["to_canonical"]
    assert set(frame) == {"scale", "rotation", "translation"}
    assert abs(frame["scale"] * SCALE - 1) < 0.01, frame
    r = np.array(frame["rotation"])
    # canonical -> capture is ROTATION, so capture -> canonical is its transpose
    angle = np.degrees(np.arccos(np.clip((np.trace(r @ ROTATION) - 1) / 2, -1, 1)))
    assert angle < 1.0, (angle, r)
    # x -> s R x + t maps the capture's offset (the canonical origin) back to the origin
    origin = frame["scale"] * r @ OFFSET + np.array(frame["translation"])
    assert np.linalg.norm(origin) < 2e-3, origin
    for k in ("residual_mm", "on_mesh_fraction", "covered_fraction", "exposed_fraction", "cost"):
        assert isinstance(fit[k], float), k
    assert fit["on_mesh_fraction"] > 0.9 and fit["scalp_error"] is None and fit["written"] == []
    # a clean head wins clearly: no warning, and any rival pose costs well more
    assert fit["warning"] is None and fit["landmarks_rms_mm"] is None and fit["landmarks_mm"] is None, fit["warning"]
    assert fit["runner_up_cost"] is None or fit["runner_up_cost"] > fit["cost"] + 0.03, fit["runner_up_cost"]
    # the fitted meshes, in the capture's frame, as read_mesh returns meshes
    for key in ("head", "scalp"):
        v, t = fit[key]
        assert v.dtype == np.float32 and v.shape[1] == 3 and t.dtype == np.uint32 and t.shape[1] == 3
    # the template is the truth: the fitted scalp's vertices are the true scalp's, within 1 mm
    v, t = fit["scalp"]
    tv, tt = truth["scalp"]
    assert np.array_equal(t, tt)
    err_mm = np.linalg.norm(v - tv, axis=1) / SCALE * 1e3
    print(f"fitted scalp vertices: mean {err_mm.mean():.3f} mm, max {err_mm.max():.3f} mm")
    assert err_mm.max() < 1.0, err_mm.max()


def test_fit_head_write_adds_the_fitted_meshes(tmp_path):
    cap = tmp_path / "cap"
    write_capture(hairrecon, cap)
    fit = hairrecon.fit_head(str(cap / "capture.json"), write=True)
    names = sorted(p.rsplit("/", 1)[-1] for p in map(str, fit["written"]))
    assert names == ["capture.json", "fitted_head.ply", "fitted_scalp.ply", "head_fit.json"], names
    spec = json.loads((cap / "capture.json").read_text())
    assert spec["scalp_mesh"] == "fitted_scalp.ply" and spec["head_mesh"] == "fitted_head.ply"
    report = json.loads((cap / "head_fit.json").read_text())
    assert report["template"] == "bundled" and abs(report["to_canonical"]["scale"] - fit["to_canonical"]["scale"]) < 1e-12
    written = hairrecon.read_mesh(str(cap / "fitted_scalp.ply"))
    assert np.allclose(written["vertices"], fit["scalp"][0])
    # the capture now has a scalp: a second fit is scored against it
    again = hairrecon.fit_head(str(cap))
    assert again["scalp_error"]["mean_mm"] < 0.1, again["scalp_error"]


def test_fit_head_on_a_sphere_raises_a_clear_error(tmp_path):
    cap = tmp_path / "cap"
    write_capture(hairrecon, cap, raw="sphere")
    with pytest.raises(hairrecon.CaptureError) as e:
        hairrecon.fit_head(str(cap))
    msg = str(e.value)
    assert "does not fit the raw mesh" in msg and "place landmarks on it (landmarks.json" in msg, msg
    assert "a scalp by hand" in msg, msg
    assert "raw.ply" in msg, msg


def test_fit_head_from_landmarks(tmp_path):
    """Landmarks beside capture.json (or given as a file) start the fit from the pose they give: the
    frame is recovered and the report says how far they lie from the template's; swapped sides are
    one error naming the file and the convention; a landmark name the library does not know too."""
    cap = tmp_path / "cap"
    write_capture(hairrecon, cap)
    names = hairrecon.head_landmarks()
    assert sorted(names) == ["chin", "ear_left", "ear_right", "eye_outer_left", "eye_outer_right", "nose_tip"]
    # the subject's left at +X, the face toward -Y, the nose tip foremost
    assert names["eye_outer_left"][0] > 0 > names["eye_outer_right"][0]
    assert names["nose_tip"][1] == min(p[1] for p in names.values())
    placed = {n: to_capture(np.array([p]))[0].tolist() for n, p in names.items()}
    (cap / "landmarks.json").write_text(json.dumps(placed))
    fit = hairrecon.fit_head(str(cap))
    frame = fit["to_canonical"]
    r = np.array(frame["rotation"])
    angle = np.degrees(np.arccos(np.clip((np.trace(r @ ROTATION) - 1) / 2, -1, 1)))
    assert angle < 1.0 and abs(frame["scale"] * SCALE - 1) < 0.01, (angle, frame["scale"])
    # the landmarks are the template's own, so the fit puts them back within a millimetre
    assert fit["landmarks_rms_mm"] is not None and fit["landmarks_rms_mm"] < 1.0, fit["landmarks_rms_mm"]
    assert sorted(fit["landmarks_mm"]) == sorted(names) and max(fit["landmarks_mm"].values()) < 1.5, fit["landmarks_mm"]
    assert hairrecon.fit_head(str(cap / "capture.json"), use_cameras=False)["landmarks_rms_mm"] < 1.0

    # the viewer's left taken for the subject's: one error naming the file and the convention
    swapped = dict(placed)
    for a, b in (("eye_outer_left", "eye_outer_right"), ("ear_left", "ear_right")):
        swapped[a], swapped[b] = placed[b], placed[a]
    other = tmp_path / "swapped.json"
    other.write_text(json.dumps(swapped))
    with pytest.raises(hairrecon.CaptureError) as e:
        hairrecon.fit_head(str(cap), landmarks=str(other))
    assert "swapped.json" in str(e.value) and "subject's own" in str(e.value), str(e.value)
    other.write_text(json.dumps({"nose": [0, 0, 0], **placed}))
    with pytest.raises(hairrecon.CaptureError, match='unknown landmark "nose"'):
        hairrecon.fit_head(str(cap), landmarks=str(other))


def test_fit_head_argument_errors(tmp_path):
    with pytest.raises(hairrecon.InputError, match="give template"):
        hairrecon.fit_head(str(tmp_path), scalp=str(tmp_path / "scalp.ply"))
    with pytest.raises(hairrecon.CaptureError):
        hairrecon.fit_head(str(tmp_path / "nothing"))
