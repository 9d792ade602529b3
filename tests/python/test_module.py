"""The Python module's file functions and exceptions: write_capture, read_image, write_image, read_exr,
read_strands, and the classes hairrecon.Error, CaptureError, FormatError, InputError, Cancelled.

Runs in a second or two, without Blender. Fixture files written by other encoders check the readers
independently of the writers (a reader and a writer that make the same mistake would pass a round
trip).
"""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest

hairrecon = pytest.importorskip("hairrecon")

# Written by the project's former numpy encoders (zlib level 6, no PNG filters; uncompressed EXR).
# 16-bit gray 3x2: [[0, 1, 258], [65535, 4660, 43981]] (big-endian samples in the file).
G16_PNG = "iVBORw0KGgoAAAANSUhEUgAAAAMAAAACEAAAAADoj+WFAAAAFklEQVR4nGNgYGBgZGRi+P9fyGT1WQAOLQPBHryRpwAAAABJRU5ErkJggg=="
# 8-bit RGBA 2x2: arange(16) * 17.
RGBA8_PNG = "iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAYAAABytg0kAAAAG0lEQVR4nGNgEFQydglNK2fomLlq95m77/4DAC8WB/nW7DLbAAAAAElFTkSuQmCC"
# 2x2 float32 channels R = [[0.5, -1], [0.001, 3]] and Z = [[1, 2], [3, 4]].
SMALL_EXR = (
    "di8xAQIAAABjaGFubmVscwBjaGxpc3QAJQAAAFIAAgAAAAAAAAABAAAAAQAAAFoAAgAAAAAAAAABAAAAAQAAAABjb21wcmVzc2lvbgBjb21w"
    "cmVzc2lvbgABAAAAAGRhdGFXaW5kb3cAYm94MmkAEAAAAAAAAAAAAAAAAQAAAAEAAABkaXNwbGF5V2luZG93AGJveDJpABAAAAAAAAAAAAAA"
    "AAEAAAABAAAAbGluZU9yZGVyAGxpbmVPcmRlcgABAAAAAHBpeGVsQXNwZWN0UmF0aW8AZmxvYXQABAAAAAAAgD9zY3JlZW5XaW5kb3dDZW50"
    "ZXIAdjJmAAgAAAAAAAAAAAAAAHNjcmVlbldpbmRvd1dpZHRoAGZsb2F0AAQAAAAAAIA/ADcBAAAAAAAATwEAAAAAAAAAAAAAEAAAAAAAAD8A"
    "AIC/AACAPwAAAEABAAAAEAAAAG8SgzoAAEBAAABAQAAAgEA="
)


def _fixture(tmp_path: Path, name: str, b64: str) -> str:
    p = tmp_path / name
    p.write_bytes(base64.b64decode(b64))
    return str(p)


# --- exceptions ----------------------------------------------------------------------------------


def test_exception_classes_form_one_hierarchy():
    assert hairrecon.HairreconError is hairrecon.Error
    assert issubclass(hairrecon.Error, Exception)
    for name in ("CaptureError", "FormatError", "InputError", "Cancelled"):
        cls = getattr(hairrecon, name)
        assert cls.__mro__[1] is hairrecon.Error, name
        assert cls.__name__ == name and cls.__module__ == "hairrecon"
    assert not issubclass(hairrecon.CaptureError, hairrecon.FormatError)


def test_a_missing_capture_is_a_capture_error():
    with pytest.raises(hairrecon.CaptureError) as e:
        hairrecon.load_capture("/nonexistent/capture")
    assert isinstance(e.value, hairrecon.Error) and isinstance(e.value, hairrecon.HairreconError)
    assert "/nonexistent/capture" in str(e.value) and "No such file" in str(e.value)


def test_a_truncated_hair_file_is_a_format_error(tmp_path):
    pts = np.arange(30, dtype=np.float32).reshape(10, 3)
    counts = np.array([4, 6], np.uint32)
    hairrecon.write_strands(str(tmp_path / "a.hair"), pts, counts)
    p, c = hairrecon.read_strands(str(tmp_path / "a.hair"))
    assert np.array_equal(p, pts) and np.array_equal(c, counts) and c.dtype == np.uint32
    data = (tmp_path / "a.hair").read_bytes()
    (tmp_path / "cut.hair").write_bytes(data[:-5])
    with pytest.raises(hairrecon.FormatError) as e:
        hairrecon.read_strands(str(tmp_path / "cut.hair"))
    assert "cut.hair" in str(e.value) and "truncated" in str(e.value)
    with pytest.raises(hairrecon.FormatError):
        hairrecon.read_mesh(str(tmp_path / "missing.ply"))
    with pytest.raises(hairrecon.FormatError, match="unsupported file extension"):
        hairrecon.read_strands(str(tmp_path / "a.xyz"))


def test_bad_arguments_are_input_errors(tmp_path):
    pts = np.zeros((4, 3), np.float32)
    with pytest.raises(hairrecon.InputError, match=r"shape \(N, 3\)"):
        hairrecon.write_strands(str(tmp_path / "a.hair"), np.zeros((4, 2), np.float32), np.array([4], np.uint32))
    with pytest.raises(hairrecon.InputError, match="strands"):
        hairrecon.write_strands(str(tmp_path / "a.hair"), pts, np.array([3], np.uint32))  # 3 != 4 points
    with pytest.raises(hairrecon.InputError, match="uint8 or uint16"):
        hairrecon.write_image(str(tmp_path / "a.png"), np.zeros((2, 2), np.float32))
    with pytest.raises(hairrecon.InputError, match="float32 or float64"):
        hairrecon.write_image(str(tmp_path / "a.exr"), np.zeros((2, 2), np.uint8))
    with pytest.raises(hairrecon.InputError, match="1 to 4 channels"):
        hairrecon.write_image(str(tmp_path / "a.png"), np.zeros((2, 2, 5), np.uint8))
    with pytest.raises(hairrecon.InputError, match="write .png or .exr"):
        hairrecon.write_image(str(tmp_path / "a.jpg"), np.zeros((2, 2), np.uint8))
    with pytest.raises(hairrecon.InputError, match="numpy array"):
        hairrecon.write_image(str(tmp_path / "a.png"), [[0, 1]])
    with pytest.raises(hairrecon.InputError, match="3 channel names"):
        hairrecon.write_image(str(tmp_path / "a.exr"), np.zeros((2, 2, 2), np.float32), channels=["X", "Y", "Z"])
    with pytest.raises(hairrecon.InputError, match="dict"):
        hairrecon.write_capture(str(tmp_path), [1, 2])
    assert list(tmp_path.iterdir()) == []


# --- images --------------------------------------------------------------------------------------


def test_images_from_other_encoders_read_to_their_values(tmp_path):
    g = hairrecon.read_image(_fixture(tmp_path, "g16.png", G16_PNG))
    assert g.dtype == np.uint16 and g.shape == (2, 3)
    assert g.tolist() == [[0, 1, 258], [65535, 4660, 43981]]
    c = hairrecon.read_image(_fixture(tmp_path, "rgba8.png", RGBA8_PNG))
    assert c.dtype == np.uint8 and c.shape == (2, 2, 4)
    assert np.array_equal(c, np.arange(16, dtype=np.uint8).reshape(2, 2, 4) * 17)
    exr = hairrecon.read_exr(_fixture(tmp_path, "small.exr", SMALL_EXR))
    assert sorted(exr) == ["R", "Z"]
    assert exr["R"].dtype == np.float32 and exr["R"].shape == (2, 2)
    assert exr["R"].tolist() == [[0.5, -1.0], [np.float32(1e-3), 3.0]]
    assert exr["Z"].tolist() == [[1, 2], [3, 4]]
    with pytest.raises(hairrecon.FormatError, match="read them by name"):
        hairrecon.read_image(str(tmp_path / "small.exr"))  # R and Z: neither R G B nor Y


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("shape", [(5, 7), (5, 7, 1), (5, 7, 2), (5, 7, 3), (5, 7, 4)])
def test_png_keeps_every_value(tmp_path, dtype, shape):
    rng = np.random.default_rng(1)
    a = rng.integers(0, np.iinfo(dtype).max, shape, endpoint=True, dtype=dtype)
    p = str(tmp_path / "a.png")
    hairrecon.write_image(p, a)
    b = hairrecon.read_image(p)
    want = a[:, :, 0] if a.ndim == 3 and a.shape[2] == 1 else a  # one channel reads as (H, W)
    assert b.dtype == dtype and b.shape == want.shape
    assert np.array_equal(b, want)
    # Bit depth by dtype: an 8-bit file is smaller than the 16-bit one of the same values.
    if dtype == np.uint8:
        hairrecon.write_image(str(tmp_path / "b.png"), a.astype(np.uint16))
        assert hairrecon.read_image(str(tmp_path / "b.png")).dtype == np.uint16


def test_strided_arrays_are_written_in_their_logical_order(tmp_path):
    a = np.arange(6 * 4 * 3, dtype=np.uint8).reshape(6, 4, 3)
    view = a[::-2, ::-1]  # negative strides, not contiguous
    hairrecon.write_image(str(tmp_path / "v.png"), view)
    assert np.array_equal(hairrecon.read_image(str(tmp_path / "v.png")), view)
    f = np.asfortranarray(np.arange(12, dtype=np.float64).reshape(3, 4) / 7)
    hairrecon.write_image(str(tmp_path / "f.exr"), f)
    back = hairrecon.read_image(str(tmp_path / "f.exr"))
    assert back.dtype == np.float32 and np.array_equal(back, f.astype(np.float32))


def test_exr_keeps_floats_bit_for_bit_with_its_channel_names(tmp_path):
    rng = np.random.default_rng(2)
    a = (rng.normal(size=(4, 6, 4)) * 10.0 ** rng.integers(-30, 30, (4, 6, 4))).astype(np.float32)
    a[0, 0, 0] = -0.0
    p = str(tmp_path / "o.exr")
    hairrecon.write_image(p, a)  # R G B A
    back = hairrecon.read_image(p)
    assert back.shape == (4, 6, 4) and np.array_equal(back.view(np.uint32), a.view(np.uint32))
    ch = hairrecon.read_exr(p)
    assert sorted(ch) == ["A", "B", "G", "R"]
    for k, name in enumerate("RGBA"):
        assert np.array_equal(ch[name], a[:, :, k])
    hairrecon.write_image(str(tmp_path / "g.exr"), a[:, :, 0])
    assert list(hairrecon.read_exr(str(tmp_path / "g.exr"))) == ["Y"]
    hairrecon.write_image(str(tmp_path / "n.exr"), a[:, :, :2], channels=["depth", "weight"])
    ch = hairrecon.read_exr(str(tmp_path / "n.exr"))
    assert np.array_equal(ch["depth"], a[:, :, 0]) and np.array_equal(ch["weight"], a[:, :, 1])


# --- strands -------------------------------------------------------------------------------------


def _hair_bytes(counts, pts) -> bytes:
    """A .hair file with a segments array (a fixture; hairrecon cannot write one-point strands)."""
    head = b"HAIR" + struct.pack("<4I", len(counts), len(pts), 3, 0) + struct.pack("<5f", 1, 0, 0, 0, 0)
    segments = (np.asarray(counts) - 1).astype("<u2")
    return head.ljust(128, b"\0") + segments.tobytes() + np.asarray(pts, "<f4").tobytes()


def test_one_point_strands_are_an_error_or_skipped(tmp_path):
    pts = np.arange(18, dtype=np.float32).reshape(6, 3)
    (tmp_path / "s.hair").write_bytes(_hair_bytes([2, 1, 3], pts))
    with pytest.raises(hairrecon.FormatError, match="skip_short_strands"):
        hairrecon.read_strands(str(tmp_path / "s.hair"))
    p, c = hairrecon.read_strands(str(tmp_path / "s.hair"), skip_short_strands=True)
    assert c.tolist() == [2, 3]
    assert np.array_equal(p, pts[[0, 1, 3, 4, 5]])


# --- capture.json --------------------------------------------------------------------------------


def _capture_files(d: Path, w=6, h=4):
    hairrecon.write_image(str(d / "images" / "v0.png"), np.zeros((h, w, 3), np.uint8))
    hairrecon.write_image(str(d / "masks" / "v0.png"), np.zeros((h, w), np.uint16))
    tri = np.array([[0, 1, 2]], np.uint32)
    hairrecon.write_mesh(str(d / "raw_mesh.ply"), np.eye(3, dtype=np.float32), tri)


def _spec(w=6, h=4):
    c, s = np.cos(0.3), np.sin(0.3)
    return {
        "version": 1,
        "units": "metres",
        "convention": "opencv",
        "views": [
            {
                "name": "v0",
                "image": Path("images/v0.png"),  # path objects are written as strings
                "mask": "masks/v0.png",
                "width": w,
                "height": h,
                "K": np.array([[100.1, 0.0, 2.5], [0.0, 100.1, 1.5], [0.0, 0.0, 1.0]]),
                "R": np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]),
                "t": [np.float32(0.1), 0.2, 1.0 / 3.0],
            }
        ],
        "raw_mesh": "raw_mesh.ply",
        "scalp_mesh": None,  # None is the field left out
    }


def test_write_capture_writes_what_load_capture_reads(tmp_path):
    d = tmp_path / "cap"
    (d / "images").mkdir(parents=True)
    (d / "masks").mkdir()
    path = hairrecon.write_capture(str(d), _spec())  # before the files exist: they are not checked
    assert Path(path) == d / "capture.json"
    _capture_files(d)
    summary = hairrecon.load_capture(str(d))
    assert summary["views"] == ["v0"] and Path(summary["raw_mesh"]) == d / "raw_mesh.ply"
    assert summary["scalp_mesh"] is None
    got = json.loads((d / "capture.json").read_text())
    assert set(got) == {"version", "units", "convention", "views", "raw_mesh"}
    v, want = got["views"][0], _spec()["views"][0]
    assert (v["name"], v["image"], v["mask"], v["width"], v["height"]) == ("v0", "images/v0.png", "masks/v0.png", 6, 4)
    # The library stores cameras as float32: the values come back rounded to float32, nothing more.
    for key in ("K", "R", "t"):
        assert np.array_equal(np.float32(v[key]), np.float32(np.asarray(want[key], dtype=np.float64))), key
    # A .json path is the file itself.
    other = hairrecon.write_capture(str(d / "copy.json"), _spec())
    assert Path(other) == d / "copy.json" and json.loads(Path(other).read_text()) == got


def test_a_bad_capture_spec_is_a_capture_error_and_writes_nothing(tmp_path):
    def fails(spec, *words):
        with pytest.raises(hairrecon.CaptureError) as e:
            hairrecon.write_capture(str(tmp_path / "cap"), spec)
        for w in words:
            assert w in str(e.value), (w, str(e.value))
        assert not (tmp_path / "cap").exists()

    s = _spec()
    del s["views"][0]["image"]
    fails(s, 'views[0] "v0"', "missing field `image`")
    s = _spec()
    s["views"][0]["K"][0, 2] = np.nan
    fails(s, 'spec["views"][0]["K"][0][2] is NaN')
    s = _spec()
    s["views"][0]["R"] = np.eye(3) * 2.0
    fails(s, '"v0"', "not a rotation")
    s = _spec()
    s["views"][0]["image"] = ""
    fails(s, 'view "v0": its image is empty')
    s = _spec()
    s["gt_strand"] = "gt/strands.hair"
    fails(s, 'unknown field "gt_strand"')
    s = _spec()
    s["views"].append(dict(s["views"][0]))
    fails(s, 'two views are named "v0"')
    s = _spec()
    s["units"] = "cubits"
    fails(s, 'unknown units "cubits"')
    s = _spec()
    s["frame"] = "y-up"
    fails(s, 'unknown frame "y-up"')
    s = _spec()
    s["views"] = []
    fails(s, "no views")
