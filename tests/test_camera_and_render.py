"""The renderer obeys the pinhole camera: pixel sizes, bearings and band colours match the geometry."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from detector.synth.objects import pole
from detector.synth.render import render_scene
from detector.synth.scene import calibration_scene
from naoslam.camera import CameraPose, PinholeCamera
from naoslam.landmarks import PoleGeometry


def _single_pole_frame(range_m: float, angle_deg: float, pitch_deg: float = 0.0, code: str = "pb"):
    camera = PinholeCamera()
    scene = calibration_scene(np.random.default_rng(0), camera, code, range_m, angle_deg)
    scene.pose = CameraPose(x=scene.pose.x, y=scene.pose.y, z=0.5, pitch=math.radians(pitch_deg))
    angle = math.radians(angle_deg)
    scene.cylinders = [pole(code, scene.pose.x + range_m * math.cos(angle), scene.pose.y + range_m * math.sin(angle), PoleGeometry())]
    return camera, scene, render_scene(scene)


@pytest.mark.parametrize("range_m", [1.5, 2.5, 5.0])
def test_projected_pole_height_follows_pinhole(range_m):
    camera, scene, frame = _single_pole_frame(range_m, 0.0)
    (truth,) = frame.poles
    rows = np.flatnonzero(truth.mask.any(axis=1))
    g, f = PoleGeometry(), camera.focal_px
    # Camera above the top: the silhouette's top is the far rim, its bottom the near foot of the tube.
    top = camera.cy + f * (scene.pose.z - g.height) / (range_m + g.radius)
    bottom = camera.cy + f * scene.pose.z / (range_m - g.radius)
    assert abs(rows[0] - top) <= 1.0
    assert abs(rows[-1] + 1 - bottom) <= 1.0
    width = np.flatnonzero(truth.mask.any(axis=0))
    expected_width = 2 * f * g.radius / math.sqrt(range_m**2 - g.radius**2)
    assert abs(len(width) - expected_width) <= 1.0


@pytest.mark.parametrize("angle_deg", [-20.0, -10.0, 0.0, 10.0, 20.0])
def test_mask_centre_column_gives_the_true_bearing(angle_deg):
    camera, _, frame = _single_pole_frame(2.0, angle_deg)
    (truth,) = frame.poles
    assert truth.bearing_rad == pytest.approx(math.radians(angle_deg), abs=1e-9)
    centre_column = np.flatnonzero(truth.mask.any(axis=0)).mean() + 0.5
    assert math.degrees(camera.bearing_of_column(centre_column)) == pytest.approx(angle_deg, abs=0.15)


def test_polygon_covers_the_band_colours():
    """Every saturated (band-coloured) pixel near the pole lies in its label, and the bands fill the label's top half."""
    from detector.datasets.polygons import mask_to_polygon, polygon_to_mask

    camera, _, frame = _single_pole_frame(1.2, 10.0, pitch_deg=8.0, code="py")
    (truth,) = frame.poles
    label = polygon_to_mask(mask_to_polygon(truth.mask), camera.width, camera.height)
    hsv = cv2.cvtColor((frame.image * 255).astype(np.uint8), cv2.COLOR_RGB2HSV)
    hue, saturated = hsv[..., 0], hsv[..., 1] > 90
    coloured = saturated & (((hue >= 140) & (hue <= 175)) | ((hue >= 20) & (hue <= 40)))  # pink, yellow
    rows, cols = np.nonzero(label)
    box = (slice(rows.min() - 5, rows.max() + 6), slice(cols.min() - 5, cols.max() + 6))
    near = np.zeros_like(label)
    near[box] = True
    assert (coloured & near & ~label).sum() <= 0.01 * (coloured & near).sum()
    top_half = label & (np.arange(camera.height)[:, None] < (rows.min() + rows.max()) / 2)
    assert (coloured & top_half).sum() >= 0.9 * top_half.sum()


def test_camera_pose_round_trip():
    pose = CameraPose(x=1.0, y=-2.0, z=0.5, yaw=0.7, pitch=0.2, roll=-0.05)
    camera = PinholeCamera()
    point = np.array([3.0, -1.0, 0.3])
    u, v = camera.project(pose.to_camera(point))
    ray = camera.pixel_rays(u, v) @ pose.world_from_camera().T
    along = pose.position + ray * pose.to_camera(point)[2]
    np.testing.assert_allclose(along, point, atol=1e-9)


def test_bearing_forms_agree_near_the_centre_and_differ_at_the_edge():
    camera = PinholeCamera()
    assert camera.bearing_of_column(camera.cx) == 0.0
    assert camera.bearing_of_column(100.0) > 0  # left of centre is positive
    assert float(camera.linear_bearing_of_column(0.0)) == pytest.approx(math.radians(56.3 / 2))
    assert float(camera.bearing_of_column(0.0)) == pytest.approx(math.radians(56.3 / 2))
    assert abs(camera.bearing_of_column(160.0) - camera.linear_bearing_of_column(160.0)) > 1e-3


@pytest.mark.parametrize("pitch_deg, shows_upper_band", [(30.0, True), (35.0, True), (40.0, False)])
def test_a_pole_is_nameable_only_while_both_bands_show(pitch_deg, shows_upper_band):
    """Looking down ever more steeply, the frame's top edge cuts the pole from above: once the upper band is gone,
    the lower band and the white base alone cannot tell the class, so the generator leaves the pole unlabelled."""
    _, _, frame = _single_pole_frame(0.8, 0.0, pitch_deg=pitch_deg)
    (truth,) = frame.poles
    (upper_shown, lower_shown), (upper_whole, lower_whole) = truth.band_pixels_shown, truth.band_pixels_whole
    assert truth.partial and lower_shown >= 0.3 * lower_whole  # the lower band shows well throughout
    assert 0 <= upper_shown < upper_whole
    assert (upper_shown >= 30) == shows_upper_band == truth.nameable
