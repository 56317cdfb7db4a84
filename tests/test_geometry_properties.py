"""Property tests (Hypothesis) of the runtime's shared models: the floor seen through a pitched and rolled camera,
the pinhole bearing, the power-law fit, the fusion of box and foot ranges, and the localisers' update."""
from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calibration.fit import fit_power_law
from naoslam.camera import NAO_HFOV_DEG, CameraPose, PinholeCamera
from naoslam.ground import GroundView
from naoslam.localisation import EifLocalisation, EkfLocalisation
from naoslam.measurement import FOOT_AGREEMENT_SIGMAS, Measurement, bearing_of_column, fuse_with_foot
from naoslam.motion import OdometryModel, wrap
from naoslam.observation import expected

EXAMPLES = settings(max_examples=200, deadline=None)
CAMERA = PinholeCamera()

#: Camera heights, pitches (down positive) and rolls a standing or walking Nao's top camera takes.
poses = st.builds(lambda z, pitch, roll: CameraPose(z=z, pitch=pitch, roll=roll), st.floats(0.3, 0.6),
                  st.floats(-0.1, 0.7), st.floats(-0.1, 0.1))
pixels = st.tuples(st.floats(0, CAMERA.width), st.floats(0, CAMERA.height))


@EXAMPLES
@given(pose=poses, pixel=pixels)
def test_a_floor_point_projects_back_to_the_pixel_it_was_seen_at(pose, pixel):
    view = GroundView(CAMERA, pose)
    point = view.ground_point(*pixel)
    below_horizon = pixel[1] > view.horizon_row(pixel[0])
    if point is None:
        assert pixel[1] <= view.horizon_row(pixel[0]) + 1e-6
        return
    assert below_horizon or abs(pixel[1] - view.horizon_row(pixel[0])) < 1e-6
    assert point[0] > 0  # the floor the camera sees lies ahead of it
    assert np.allclose(view.project(np.array([*point, 0.0])), pixel, atol=1e-6)


@EXAMPLES
@given(bearing=st.floats(-math.radians(NAO_HFOV_DEG) / 2, math.radians(NAO_HFOV_DEG) / 2),
       width=st.sampled_from([320, 640, 1280]))
def test_the_pinhole_bearing_of_a_column_undoes_the_projection_of_that_bearing(bearing, width):
    camera = PinholeCamera(width, width * 3 // 4)
    column = float(camera.project(np.array([-math.sin(bearing), 0.0, math.cos(bearing)]))[0])
    assert abs(bearing_of_column(column, width, NAO_HFOV_DEG) - bearing) < 1e-12
    assert 0 <= column <= width


@EXAMPLES
@given(a=st.floats(20, 2000), b=st.floats(-1.3, -0.7),
       ranges=st.lists(st.floats(0.3, 9), min_size=2, max_size=30).filter(lambda v: np.ptp(v) > 0.01))
def test_the_power_law_fit_recovers_any_law_from_exact_sizes(a, b, ranges):
    ranges = np.array(ranges)
    law, r2 = fit_power_law((ranges / a) ** (1 / b), ranges)
    assert math.isclose(law.a, a, rel_tol=1e-6) and math.isclose(law.b, b, rel_tol=1e-6)
    assert law.relative_std < 1e-9 and r2 > 1 - 1e-9


@EXAMPLES
@given(box=st.floats(0.3, 9), box_std=st.floats(0.01, 1), foot=st.floats(0.3, 9), foot_std=st.floats(0.01, 1))
def test_the_fused_range_lies_between_the_two_and_is_surer_than_either(box, box_std, foot, foot_std):
    fused = fuse_with_foot(box, box_std, foot, foot_std)
    if abs(box - foot) > FOOT_AGREEMENT_SIGMAS * math.hypot(box_std, foot_std):
        assert fused is None
        return
    range_m, std = fused
    assert min(box, foot) - 1e-12 <= range_m <= max(box, foot) + 1e-12
    assert std <= min(box_std, foot_std)


@st.composite
def _sightings(draw) -> tuple[np.ndarray, np.ndarray, tuple[float, float], Measurement]:
    """A pose, an SPD pose covariance, a mapped pole 1-8 m away in view and a noisy sighting of it."""
    pose = np.array([draw(st.floats(-4, 4)), draw(st.floats(-3, 3)), draw(st.floats(-math.pi, math.pi))])
    spread = np.array(draw(st.lists(st.floats(-0.3, 0.3), min_size=9, max_size=9))).reshape(3, 3)
    cov = spread @ spread.T + np.diag([1e-4, 1e-4, 1e-5])
    distance, angle = draw(st.floats(1, 8)), draw(st.floats(-0.5, 0.5))
    landmark = (pose[0] + distance * math.cos(pose[2] + angle), pose[1] + distance * math.sin(pose[2] + angle))
    truth = expected(pose, np.array(landmark))
    sighting = Measurement(max(0.05, truth[0] + draw(st.floats(-0.3, 0.3))), truth[1] + draw(st.floats(-0.1, 0.1)),
                           "bp", 1.0, draw(st.floats(0.02, 0.5)), draw(st.floats(0.01, 0.1)))
    return pose, cov, landmark, sighting


@EXAMPLES
@given(case=_sightings())
def test_a_sighting_never_makes_the_localiser_less_sure_and_the_ekf_and_eif_agree(case):
    pose, cov, landmark, sighting = case
    ekf = EkfLocalisation(pose, cov, {"bp": landmark}, OdometryModel(), gate=None)
    eif = EifLocalisation(pose, cov, {"bp": landmark}, OdometryModel(), gate=None)
    before = ekf.sigma.copy()
    assert ekf.update([sighting]) == 1
    eif.update([sighting])
    assert np.array_equal(ekf.sigma, ekf.sigma.T)
    assert np.linalg.eigvalsh(ekf.sigma).min() > 0
    assert np.linalg.eigvalsh(before - ekf.sigma).min() > -1e-9  # information only added
    assert np.allclose(ekf.pose[:2], eif.pose[:2], atol=1e-7) and abs(wrap(ekf.pose[2] - eif.pose[2])) < 1e-7
    assert np.allclose(eif.covariance(), ekf.sigma, atol=1e-7)
