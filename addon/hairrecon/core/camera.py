"""Blender cameras <-> OpenCV pinhole cameras (K, R, t), exactly.

Conventions (docs/method.md): ``x_img = K (R X + t)``, camera x right, y down, z forward, pixel
centres at integer coordinates. Blender's camera looks down its local -Z with +Y up.

Blender side (checked on bpy 5.0.1, see blender-notes.md "Cameras -> OpenCV K, R, t"):

- W, H = render resolution x percentage / 100 (integer, as Blender computes it);
  pixel aspect pa = pixel_aspect_y / pixel_aspect_x.
- Sensor fit AUTO -> HORIZONTAL when pixel_aspect_x * W >= pixel_aspect_y * H, else VERTICAL.
  view = W for a horizontal fit, pa * H for a vertical one; the sensor size used is sensor_height only
  when the fit is explicitly VERTICAL, else sensor_width.
- fx = lens / sensor * view, fy = fx / pa, cx = (W - 1)/2 - shift_x * view,
  cy = (H - 1)/2 + shift_y * view / pa.
- M = matrix_world with its axes normalised; R = diag(1, -1, -1) M[:3,:3]^T; t = -R M[:3,3].

All functions take plain numbers / nested lists / numpy arrays, never bpy objects, except
:func:`blender_camera`, which reads those numbers from a camera object and a scene (any objects with
their attributes; this module does not import bpy). This is the one Blender-to-OpenCV conversion of
the project: the add-on, ``scripts/render_synthetic.py`` and the tests use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_FLIP = np.diag([1.0, -1.0, -1.0])


class CameraInputError(ValueError):
    """A camera cannot be turned into a pinhole camera; the message names the camera and the fix."""


@dataclass(frozen=True)
class BlenderCamera:
    """What the conversion needs from a Blender camera object and the scene's render settings."""

    name: str
    matrix_world: np.ndarray  # (4, 4)
    lens: float  # mm
    sensor_width: float  # mm
    sensor_height: float  # mm
    sensor_fit: str  # 'AUTO' | 'HORIZONTAL' | 'VERTICAL'
    shift_x: float = 0.0
    shift_y: float = 0.0
    resolution_x: int = 1920
    resolution_y: int = 1080
    resolution_percentage: int = 100
    pixel_aspect_x: float = 1.0
    pixel_aspect_y: float = 1.0
    type: str = "PERSP"


@dataclass(frozen=True)
class PinholeCamera:
    """An OpenCV camera: row-major K (3x3), R (3x3), t (3), image size in pixels."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel positions (N, 2) and depths (N,) of world points (N, 3)."""
        pc = np.asarray(points, dtype=np.float64) @ self.R.T + self.t
        z = pc[:, 2]
        uvw = pc @ self.K.T
        return uvw[:, :2] / z[:, None], z

    def to_json(self) -> dict:
        return {
            "width": int(self.width),
            "height": int(self.height),
            "K": [[float(v) for v in row] for row in self.K],
            "R": [[float(v) for v in row] for row in self.R],
            "t": [float(v) for v in self.t],
        }


def blender_camera(obj, scene) -> BlenderCamera:
    """What :func:`opencv_from_blender` needs from a Blender camera object and its scene's render
    settings (``bpy.types.Object`` and ``bpy.types.Scene``, read by attribute)."""
    cam = obj.data
    r = scene.render
    return BlenderCamera(
        name=obj.name,
        matrix_world=np.array(obj.matrix_world, dtype=np.float64),
        lens=cam.lens,
        sensor_width=cam.sensor_width,
        sensor_height=cam.sensor_height,
        sensor_fit=cam.sensor_fit,
        shift_x=cam.shift_x,
        shift_y=cam.shift_y,
        resolution_x=r.resolution_x,
        resolution_y=r.resolution_y,
        resolution_percentage=r.resolution_percentage,
        pixel_aspect_x=r.pixel_aspect_x,
        pixel_aspect_y=r.pixel_aspect_y,
        type=cam.type,
    )


def render_size(resolution_x: int, resolution_y: int, percentage: int) -> tuple[int, int]:
    """The rendered image size in pixels, as Blender computes it (integer division)."""
    return resolution_x * percentage // 100, resolution_y * percentage // 100


def _effective_fit(cam: BlenderCamera, width: int, height: int) -> str:
    if cam.sensor_fit == "AUTO":
        return "HORIZONTAL" if cam.pixel_aspect_x * width >= cam.pixel_aspect_y * height else "VERTICAL"
    return cam.sensor_fit


def intrinsics(cam: BlenderCamera) -> tuple[np.ndarray, int, int]:
    """K (3x3, float64) and the image size (W, H) of a Blender camera under its render settings."""
    if cam.type != "PERSP":
        raise CameraInputError(
            f"camera {cam.name!r} is {cam.type.lower()}, not perspective; hairrecon needs pinhole "
            "(perspective) cameras: set Camera Properties > Lens > Type to Perspective"
        )
    if not (np.isfinite(cam.lens) and cam.lens >= 1.0 - 1e-6):
        raise CameraInputError(
            f"camera {cam.name!r} has a focal length of {cam.lens:.6g} mm; it must be at least 1 mm "
            "(Camera Properties > Lens > Focal Length)"
        )
    sensor = cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width
    if not (np.isfinite(sensor) and sensor > 0):
        raise CameraInputError(f"camera {cam.name!r} has a sensor size of {sensor} mm; it must be positive")
    width, height = render_size(cam.resolution_x, cam.resolution_y, cam.resolution_percentage)
    if width <= 0 or height <= 0:
        raise CameraInputError(
            f"the render resolution {width}x{height} is empty; set Output Properties > Format > Resolution"
        )
    pa = cam.pixel_aspect_y / cam.pixel_aspect_x
    view = width if _effective_fit(cam, width, height) == "HORIZONTAL" else pa * height
    fx = cam.lens / sensor * view
    fy = fx / pa
    cx = (width - 1) / 2.0 - cam.shift_x * view
    cy = (height - 1) / 2.0 + cam.shift_y * view / pa
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return K, width, height


def extrinsics(name: str, matrix_world) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera R (3x3) and t (3) from a Blender camera's world matrix (scale removed)."""
    m = np.asarray(matrix_world, dtype=np.float64).reshape(4, 4)
    if not np.all(np.isfinite(m)):
        raise CameraInputError(f"camera {name!r} has a non-finite transform")
    axes = m[:3, :3]
    norms = np.linalg.norm(axes, axis=0)
    if np.any(norms < 1e-12):
        raise CameraInputError(f"camera {name!r} has a zero scale; give it a non-zero scale (Object > Transform)")
    rot = axes / norms
    if np.abs(rot.T @ rot - np.eye(3)).max() > 1e-5:
        raise CameraInputError(
            f"camera {name!r} has a sheared transform (is it parented to a non-uniformly scaled object?); "
            "cameras must be rigid"
        )
    if np.linalg.det(rot) < 0:
        raise CameraInputError(f"camera {name!r} is mirrored (negative scale); give it a positive scale")
    R = _FLIP @ rot.T
    t = -R @ m[:3, 3]
    return R, t


def opencv_from_blender(cam: BlenderCamera) -> PinholeCamera:
    """The OpenCV camera that projects world points to the same pixels as Blender renders them."""
    K, width, height = intrinsics(cam)
    R, t = extrinsics(cam.name, cam.matrix_world)
    return PinholeCamera(K=K, R=R, t=t, width=width, height=height)


def rescale(cam: PinholeCamera, width: int, height: int, tol: float = 0.01) -> PinholeCamera:
    """The same camera for an image of another size with the same aspect ratio (e.g. a photo at full
    size when the render resolution is smaller). Pixel centres stay at integers: u' = (u + 0.5) s - 0.5."""
    if (width, height) == (cam.width, cam.height):
        return cam
    sx, sy = width / cam.width, height / cam.height
    if abs(sx / sy - 1.0) > tol:
        raise ValueError(f"aspect ratio {width}x{height} differs from {cam.width}x{cam.height}")
    S = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5], [0.0, 0.0, 1.0]])
    return PinholeCamera(K=S @ cam.K, R=cam.R, t=cam.t, width=width, height=height)


@dataclass(frozen=True)
class BlenderCameraSettings:
    """Camera data and render settings that reproduce an OpenCV camera in Blender."""

    lens: float
    sensor_width: float
    sensor_fit: str
    shift_x: float
    shift_y: float
    resolution_x: int
    resolution_y: int
    pixel_aspect_x: float
    pixel_aspect_y: float
    matrix_world: np.ndarray  # (4, 4)
    skew: float  # K[0][1]; Blender cameras have none, so it is dropped (reported by the caller)


def blender_from_opencv(cam: PinholeCamera, sensor_width: float = 36.0) -> BlenderCameraSettings:
    """Inverse of :func:`opencv_from_blender`, with an explicit HORIZONTAL fit and 100% resolution."""
    K = np.asarray(cam.K, dtype=np.float64)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    W, H = int(cam.width), int(cam.height)
    pa = fx / fy  # pixel_aspect_y / pixel_aspect_x
    pax, pay = (1.0, pa) if pa >= 1.0 else (1.0 / pa, 1.0)
    view = W
    R = np.asarray(cam.R, dtype=np.float64)
    t = np.asarray(cam.t, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = (_FLIP @ R).T
    m[:3, 3] = -R.T @ t
    return BlenderCameraSettings(
        lens=fx * sensor_width / view,
        sensor_width=sensor_width,
        sensor_fit="HORIZONTAL",
        shift_x=((W - 1) / 2.0 - cx) / view,
        shift_y=(cy - (H - 1) / 2.0) * pa / view,
        resolution_x=W,
        resolution_y=H,
        pixel_aspect_x=pax,
        pixel_aspect_y=pay,
        matrix_world=m,
        skew=float(K[0, 1]),
    )
