"""The Python module's importers: hairrecon.import_colmap, import_metashape, import_nerf.

A tiny COLMAP text model written by hand (colmap_fixture.py: two PINHOLE cameras, 640x480 photos)
is imported at a working height of 240 and checked against the K scaling worked out by hand, the
frame and units, the progress callback (on this thread; False cancels; an exception is raised again)
and the errors (their class and the file they name). Runs in a second or two, without Blender.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest

from colmap_fixture import expected_k, write_colmap_model

hairrecon = pytest.importorskip("hairrecon")


def leftovers(folder: Path) -> list[str]:
    """Hidden staging folders the importer may have left beside the capture."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_import_colmap_scales_k_and_keeps_the_tools_frame(tmp_path):
    m = write_colmap_model(tmp_path / "src")
    calls = []
    main = threading.get_ident()
    out = tmp_path / "capture"
    done = hairrecon.import_colmap(
        m["sparse"], m["images"], m["mesh"], str(out), height=240,
        progress=lambda d, t: calls.append((d, t, threading.get_ident() == main)),
    )
    assert Path(done["capture"]) == out / "capture.json"
    assert isinstance(done["warnings"], list)
    # called once per photo, always on the calling thread (bpy is not thread-safe)
    assert sorted(calls) == [(1, 2, True), (2, 2, True)]
    summary = hairrecon.load_capture(str(out))
    assert summary["num_views"] == 2 and sorted(summary["views"]) == ["view_a", "view_b"]
    spec = json.loads((out / "capture.json").read_text())
    assert spec["frame"] == "imported" and spec["units"] == "unknown" and spec["convention"] == "opencv"
    views = {v["name"]: v for v in spec["views"]}
    for name, want in m["views"].items():
        v = views[name]
        assert (v["width"], v["height"]) == (320, 240)
        assert hairrecon.read_image(str(out / v["image"])).shape[:2] == (240, 320)
        # fx halves; cx' = 0.5 (cx + 0.5) - 0.5 with cx = cx_colmap - 0.5
        np.testing.assert_allclose(np.array(v["K"]), expected_k(want, 240), atol=1e-4)
        np.testing.assert_allclose(np.array(v["R"]), np.array(want["R"]), atol=1e-6)
        np.testing.assert_allclose(np.array(v["t"]), np.array(want["t"]), atol=1e-6)
        assert Path(v["original"]) == (Path(m["images"]) / f"{name}.png").resolve()
    k = np.array(views["view_a"]["K"])
    assert k[0, 0] == pytest.approx(250.0) and k[0, 2] == pytest.approx(0.5 * 330.0 - 0.5)
    mesh = hairrecon.read_mesh(str(out / spec["raw_mesh"]))
    assert mesh["triangles"].shape == (8, 3)


def test_import_nerf_finds_the_photos_beside_the_transforms(tmp_path):
    """transforms.json of the same cameras (OpenGL camera-to-world): the same capture, with the
    photos' folder defaulting to the file's folder."""
    m = write_colmap_model(tmp_path / "src")
    frames = []
    for name, v in m["views"].items():
        r, t = np.array(v["R"]), np.array(v["t"])
        c2w = np.eye(4)
        c2w[:3, :3], c2w[:3, 3] = r.T, -r.T @ t
        c2w[:3, 1:3] *= -1  # OpenCV camera axes -> OpenGL
        fx, fy, cx, cy = v["colmap_k"]
        frames.append({"file_path": f"photos/{name}.png", "transform_matrix": c2w.tolist(),
                       "fl_x": fx, "fl_y": fy, "cx": cx, "cy": cy})
    tf = tmp_path / "src" / "transforms.json"
    tf.write_text(json.dumps({"camera_model": "PINHOLE", "w": 640, "h": 480, "frames": frames}))
    done = hairrecon.import_nerf(str(tf), m["mesh"], str(tmp_path / "capture"), height=240)
    spec = json.loads(Path(done["capture"]).read_text())
    for v in spec["views"]:
        want = m["views"][v["name"]]
        np.testing.assert_allclose(np.array(v["K"]), expected_k(want, 240), atol=1e-4)
        np.testing.assert_allclose(np.array(v["R"]), np.array(want["R"]), atol=1e-6)
        np.testing.assert_allclose(np.array(v["t"]), np.array(want["t"]), atol=1e-6)


def test_a_missing_photo_is_a_format_error_naming_it_and_writes_nothing(tmp_path):
    m = write_colmap_model(tmp_path / "src", missing_photo="view_b.png")
    out = tmp_path / "capture"
    with pytest.raises(hairrecon.FormatError) as e:
        hairrecon.import_colmap(m["sparse"], m["images"], m["mesh"], str(out), height=240)
    assert "view_b.png" in str(e.value) and "does not exist" in str(e.value)
    assert not out.exists() and leftovers(tmp_path) == []


def test_progress_returning_false_cancels_and_writes_nothing(tmp_path):
    m = write_colmap_model(tmp_path / "src")
    out = tmp_path / "capture"
    calls = []

    def stop(done, total):
        calls.append(done)
        return False

    with pytest.raises(hairrecon.Cancelled) as e:
        hairrecon.import_colmap(m["sparse"], m["images"], m["mesh"], str(out), height=240, progress=stop)
    assert "cancelled" in str(e.value)
    assert len(calls) == 1  # not asked again once it said stop
    assert not out.exists() and leftovers(tmp_path) == []
    # None (a callback without a return) goes on
    hairrecon.import_colmap(m["sparse"], m["images"], m["mesh"], str(out), height=240, progress=lambda d, t: None)
    assert (out / "capture.json").is_file()


def test_an_exception_in_progress_cancels_and_is_raised_again(tmp_path):
    m = write_colmap_model(tmp_path / "src")
    out = tmp_path / "capture"

    class Stop(Exception):
        pass

    def boom(done, total):
        raise Stop(f"stopped at {done}/{total}")

    with pytest.raises(Stop, match="stopped at 1/2"):
        hairrecon.import_colmap(m["sparse"], m["images"], m["mesh"], str(out), height=240, progress=boom)
    assert not out.exists() and leftovers(tmp_path) == []


def test_import_errors_have_their_class_and_name_the_file(tmp_path):
    m = write_colmap_model(tmp_path / "src")
    args = (m["images"], m["mesh"])
    # a folder that is not a COLMAP model, a calibration file that does not exist: InputError
    with pytest.raises(hairrecon.InputError, match="not a COLMAP sparse model"):
        hairrecon.import_colmap(m["images"], *args, str(tmp_path / "a"))
    with pytest.raises(hairrecon.InputError, match="cams.xml"):
        hairrecon.import_metashape(str(tmp_path / "cams.xml"), m["mesh"], str(tmp_path / "a"))
    with pytest.raises(hairrecon.InputError, match="transforms.json"):
        hairrecon.import_nerf(str(tmp_path / "transforms.json"), m["mesh"], str(tmp_path / "a"))
    with pytest.raises(hairrecon.InputError, match="height"):
        hairrecon.import_colmap(m["sparse"], *args, str(tmp_path / "a"), height=0)
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "x.txt").write_text("x")
    with pytest.raises(hairrecon.InputError, match="not empty"):
        hairrecon.import_colmap(m["sparse"], *args, str(busy))
    # a malformed calibration: FormatError naming the file and line
    cams = Path(m["sparse"]) / "cameras.txt"
    good = cams.read_text()
    cams.write_text(good.replace("PINHOLE 640 480 500.0", "PINHOLE 640 480 five"))
    with pytest.raises(hairrecon.FormatError, match=r"cameras\.txt, line 2"):
        hairrecon.import_colmap(m["sparse"], *args, str(tmp_path / "a"))
    cams.write_text(good)
    # a photo of another size than its camera: CaptureError
    hairrecon.write_image(str(Path(m["images"]) / "view_a.png"), np.zeros((100, 100, 3), np.uint8))
    with pytest.raises(hairrecon.CaptureError, match="view_a.png"):
        hairrecon.import_colmap(m["sparse"], *args, str(tmp_path / "a"))
    # a missing raw mesh: FormatError naming it
    with pytest.raises(hairrecon.FormatError, match="nomesh.ply"):
        hairrecon.import_colmap(m["sparse"], m["images"], str(tmp_path / "nomesh.ply"), str(tmp_path / "a"))
    assert not (tmp_path / "a").exists()
