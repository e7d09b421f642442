"""Pinhole intrinsics from the calibration files depth cameras come with.

Read formats:

- ROS ``camera_info`` YAML: the ``ost.yaml`` that ROS's ``camera_calibration`` writes
  (``image_width``, ``image_height``, ``camera_matrix: {rows, cols, data}``,
  ``distortion_coefficients``), or a ``sensor_msgs/CameraInfo`` message echoed as YAML
  (``rostopic echo`` in ROS 1: ``width``, ``height``, ``K``, ``D``; ``ros2 topic echo``:
  ``k``, ``d``);
- OpenCV calibration files written by ``cv::FileStorage`` (YAML with ``!!opencv-matrix``
  tags, or XML), e.g. from OpenCV's calibration sample: ``camera_matrix`` (or
  ``cameraMatrix``, ``K``), ``image_width``, ``image_height``, ``distortion_coefficients``.

Focal lengths and principal point are in pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from lsd.io import DataFileError

_MATRIX_KEYS = ("camera_matrix", "K", "k", "cameraMatrix", "intrinsic_matrix")
_DISTORTION_KEYS = ("distortion_coefficients", "D", "d", "dist_coeffs", "distCoeffs")
_WIDTH_KEYS = ("image_width", "width")
_HEIGHT_KEYS = ("image_height", "height")


@dataclass(frozen=True)
class CameraInfo:
    """A camera's pinhole intrinsics as its calibration file gives them.

    Attributes:
        fx, fy: focal lengths (pixels).
        cx, cy: principal point (pixels).
        width, height: the calibrated image size (pixels), or None when the file has none.
        distortion: lens distortion coefficients (empty when the file has none).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int | None = None
    height: int | None = None
    distortion: tuple[float, ...] = ()

    @property
    def distorted(self) -> bool:
        """Whether any distortion coefficient is nonzero (the image is not rectified)."""
        return any(c != 0.0 for c in self.distortion)


def read_camera_info(path: str | Path) -> CameraInfo:
    """Read ``path`` (a ROS camera_info YAML or an OpenCV calibration file, see the module);
    raises :class:`lsd.io.DataFileError` naming the file and the field at fault."""
    p = Path(path)
    try:
        head = p.read_bytes()[:4096]
    except OSError as exc:
        raise DataFileError(f"{p}: cannot read ({exc.strerror})") from None
    # OpenCV's files: XML, or YAML with its own matrix tags (and a "%YAML:1.0" line before
    # OpenCV 4) that a plain YAML reader refuses.
    if head.lstrip().startswith((b"%YAML:", b"<?xml")) or b"!!opencv-" in head:
        fields = _read_opencv(p)
    else:
        fields = _read_ros(p)
    return _camera_info(p, fields)


def _read_ros(p: Path) -> dict[str, Any]:
    """The first mapping of a YAML file (``rostopic echo`` ends each message with ``---``)."""
    try:
        documents = list(yaml.safe_load_all(p.read_text(encoding="utf-8")))
    except UnicodeDecodeError:
        raise DataFileError(f"{p}: not a text file (expected camera_info YAML)") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        reason = getattr(exc, "problem", None) or "not valid YAML"
        raise DataFileError(f"{p}:{where}: {reason}") from None
    for document in documents:
        if isinstance(document, dict):
            return document
    raise DataFileError(f"{p}: no camera_info mapping in the file")


def _read_opencv(p: Path) -> dict[str, Any]:
    """The calibration nodes of a cv::FileStorage file, as plain values."""
    import cv2

    unreadable = DataFileError(f"{p}: not a readable OpenCV calibration file")
    try:
        storage = cv2.FileStorage(str(p), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError):  # the binding raises SystemError around a parse error
        raise unreadable from None
    try:
        if not storage.isOpened():
            raise unreadable
        fields: dict[str, Any] = {}
        for key in (*_MATRIX_KEYS, *_DISTORTION_KEYS):
            node = storage.getNode(key)
            if node.isNone():
                continue
            value = node.mat() if node.isMap() else None
            if value is None and node.isSeq():
                value = [node.at(i).real() for i in range(node.size())]
            fields[key] = value
        for key in (*_WIDTH_KEYS, *_HEIGHT_KEYS):
            node = storage.getNode(key)
            if not node.isNone():
                fields[key] = node.real()
        return fields
    except (cv2.error, SystemError):
        raise unreadable from None
    finally:
        storage.release()


def _first(fields: dict[str, Any], keys: tuple[str, ...]) -> tuple[str, Any] | None:
    for key in keys:
        if key in fields and fields[key] is not None:
            return key, fields[key]
    return None


def _numbers(p: Path, key: str, value: Any) -> tuple[str, np.ndarray]:
    """The numbers of a matrix field (a list, a ``{rows, cols, data}`` mapping, or an array)
    and the field's name for messages."""
    if isinstance(value, dict):
        if "data" not in value:
            raise DataFileError(f"{p}: {key}: expected a 'data' list")
        key, value = f"{key}.data", value["data"]
    try:
        numbers = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise DataFileError(f"{p}: {key}: expected numbers") from None
    if not np.isfinite(numbers).all():
        raise DataFileError(f"{p}: {key}: not finite")
    return key, numbers


def _size(p: Path, fields: dict[str, Any], keys: tuple[str, ...]) -> int | None:
    found = _first(fields, keys)
    if found is None:
        return None
    key, value = found
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
        math.isfinite(value) and value == int(value) and value >= 0
    ):
        raise DataFileError(f"{p}: {key}: expected a whole number of pixels, got {value!r}")
    return int(value) or None  # an uncalibrated CameraInfo says 0: no size


def _camera_info(p: Path, fields: dict[str, Any]) -> CameraInfo:
    found = _first(fields, _MATRIX_KEYS)
    if found is None:
        raise DataFileError(
            f"{p}: no camera matrix (looked for {', '.join(_MATRIX_KEYS[:3])})"
        )
    key, k = _numbers(p, *found)
    if k.size != 9:
        raise DataFileError(f"{p}: {key}: expected a 3 x 3 matrix (9 numbers), got {k.size}")
    k = k.reshape(3, 3)
    if not k.any():
        raise DataFileError(f"{p}: {key}: all zeros (the camera was not calibrated)")
    if not np.array_equal(k[2], [0.0, 0.0, 1.0]) or k[1, 0] != 0.0:
        raise DataFileError(f"{p}: {key}: not a pinhole camera matrix [fx s cx; 0 fy cy; 0 0 1]")
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise DataFileError(
            f"{p}: {key}: focal lengths must be positive, got fx {k[0, 0]:g}, fy {k[1, 1]:g}"
            " (an uncalibrated camera?)"
        )
    distortion: tuple[float, ...] = ()
    found = _first(fields, _DISTORTION_KEYS)
    if found is not None:
        distortion = tuple(float(c) for c in _numbers(p, *found)[1])
    return CameraInfo(
        fx=float(k[0, 0]), fy=float(k[1, 1]), cx=float(k[0, 2]), cy=float(k[1, 2]),
        width=_size(p, fields, _WIDTH_KEYS), height=_size(p, fields, _HEIGHT_KEYS),
        distortion=distortion,
    )
