"""The naoslam back ends: Jacobians, consistency, variants, localisation, the simulator and the UTIAS loader."""
from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from naoslam import observation
from naoslam.ekf_slam import EkfSlam, SlamConfig
from naoslam.localisation import EifLocalisation, EkfLocalisation
from naoslam.logs import load_optitrack, load_utias
from naoslam.measurement import Measurement
from naoslam.metrics import fit_se2
from naoslam.motion import OdometryModel, VelocityModel, wrap
from naoslam.runner import Event, Sequence, SlamResult, merge_frames, run_slam, walk_sequence
from naoslam.sim import SimConfig, simulate

from tests.conftest import SHARED

NOISE_FREE = dict(false_positive_rate=0.0, miss_rate=0.0, range_rel_std=0.0, bearing_std_deg=0.0, stride_scale=1.0,
                  turn_bias=0.0, odometry_noise=(0.0, 0.0))


def _numeric_jacobian(f, x, eps=1e-6):
    x = np.asarray(x, float)
    columns = []
    for i in range(len(x)):
        step = np.zeros_like(x)
        step[i] = eps
        diff = np.asarray(f(x + step)) - np.asarray(f(x - step))
        if len(diff) == 3:
            diff[2] = wrap(diff[2])
        elif len(diff) == 2 and f.__name__ == "measure":
            diff[1] = wrap(diff[1])
        columns.append(diff / (2 * eps))
    return np.stack(columns, axis=1)


@pytest.mark.parametrize("model, u", [(OdometryModel(), np.array([0.3, 0.2, -0.1])),
                                      (VelocityModel(), np.array([0.2, 0.4, 0.5])),
                                      (VelocityModel(), np.array([0.2, 0.0, 0.5]))])
def test_motion_jacobians_match_finite_differences(model, u):
    pose = np.array([0.4, -1.2, 2.9])
    g, v = model.jacobians(pose, u)
    assert np.allclose(g, _numeric_jacobian(lambda p: model.move(p, u), pose), atol=1e-5)
    controls = (lambda c: model.move(pose, c)) if isinstance(model, OdometryModel) else \
        (lambda c: model.move(pose, np.r_[c, u[2]]))
    assert np.allclose(v, _numeric_jacobian(controls, u if isinstance(model, OdometryModel) else u[:2]), atol=1e-4)


def test_observation_jacobians_and_inverse_match_finite_differences():
    pose, landmark = np.array([1.0, 0.5, 3.0]), np.array([-2.0, 2.2])

    def measure(x):
        return observation.expected(x[:3], x[3:])

    numeric = _numeric_jacobian(measure, np.r_[pose, landmark])
    h_pose, h_landmark = observation.jacobians(pose, landmark)
    assert np.allclose(np.hstack([h_pose, h_landmark]), numeric, atol=1e-5)
    z = observation.expected(pose, landmark)
    position, j_pose, j_z = observation.landmark_from(pose, z)
    assert np.allclose(position, landmark)
    assert np.allclose(j_pose, _numeric_jacobian(lambda p: observation.landmark_from(p, z)[0], pose), atol=1e-5)
    assert np.allclose(j_z, _numeric_jacobian(lambda zz: observation.landmark_from(pose, zz)[0], z), atol=1e-5)


def test_odometry_control_reproduces_the_move():
    a, b = np.array([0.2, -0.4, 0.3]), np.array([0.9, 0.1, -2.8])
    assert np.allclose(OdometryModel.move(a, OdometryModel.control(a, b)), b)


@pytest.mark.parametrize("config", [SlamConfig.thesis(), SlamConfig.thesis(linearisation="fej"),
                                    SlamConfig.thesis(outlier_filter=True), SlamConfig.thesis(gate=9.21),
                                    SlamConfig.thesis(min_views=3), SlamConfig(), SlamConfig(linearisation="standard"),
                                    SlamConfig(linearisation="fej", min_views=5), SlamConfig(association="class")])
def test_every_back_end_converges_to_the_truth_without_noise(config):
    walk = simulate(SimConfig(seed=3, **NOISE_FREE))
    metrics = run_slam(walk_sequence(walk), config).metrics()
    assert metrics["robot_error"]["mean"] < 1e-6
    assert metrics["landmark_error"]["mean"] < 1e-6 and metrics["landmark_error"]["mapped"] == 6


def test_covariance_stays_symmetric_positive_definite_on_a_long_run():
    walk = simulate(SimConfig(duration_s=300, seed=5))
    slam = EkfSlam(walk.steps[0].true_pose, np.eye(3) * 1e-4, OdometryModel(walk.config.odometry_alphas()),
                   SlamConfig())
    for previous, step in zip(walk.steps, walk.steps[1:]):
        slam.predict(OdometryModel.control(previous.odometry_pose, step.odometry_pose))
        if step.measurements:
            slam.update(step.measurements)
    assert np.array_equal(slam.sigma, slam.sigma.T)
    assert np.linalg.eigvalsh(slam.sigma).min() > 0
    assert set(slam.landmarks) == set(walk.landmarks)


def test_fej_and_classic_agree_while_their_linearisation_points_coincide():
    """Until the first correction of a mapped landmark, FEJ's points equal the current estimates."""
    walk = simulate(SimConfig(seed=2, false_positive_rate=0.0))
    sequence = walk_sequence(walk)
    first_correction = None
    seen: set[str] = set()
    for i, event in enumerate(sequence.events):
        for m in event.measurements or []:
            if m.signature in seen and first_correction is None:
                first_correction = i
            seen.add(m.signature)
    assert first_correction and first_correction > 1
    head = replace(sequence, events=sequence.events[:first_correction + 1])
    classic, fej = run_slam(head, SlamConfig.thesis()), run_slam(head, SlamConfig.thesis(linearisation="fej"))
    assert np.allclose(classic.poses, fej.poses, atol=1e-12)
    longer = replace(sequence, events=sequence.events[:first_correction + 40])
    assert not np.allclose(run_slam(longer, SlamConfig.thesis()).poses,
                           run_slam(longer, SlamConfig.thesis(linearisation="fej")).poses)


def _mapped_slam(config: SlamConfig) -> EkfSlam:
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), config)
    slam.update([Measurement(2.0, 0.1, "bp", 1.0, 0.05, 0.02)])
    return slam


@pytest.mark.parametrize("config", [SlamConfig.thesis(outlier_filter=True), SlamConfig.thesis(gate=9.21)])
def test_outlier_filter_and_gate_reject_a_false_positive(config):
    slam = _mapped_slam(config)
    before = slam.mu.copy()
    log = slam.update([Measurement(3.5, -0.6, "bp", 0.9, 0.1, 0.03)])  # 1.5 m and 40 deg off the prediction
    assert log.rejected == ["bp"] and np.array_equal(slam.mu, before)
    assert slam.update([Measurement(2.02, 0.11, "bp", 0.9, 0.05, 0.02)]).accepted == ["bp"]
    unfiltered = _mapped_slam(SlamConfig.thesis())
    assert unfiltered.update([Measurement(3.5, -0.6, "bp", 0.9, 0.1, 0.03)]).accepted == ["bp"]


@pytest.mark.parametrize("min_views", [1, 3])
def test_with_known_correspondences_a_second_detection_of_a_class_never_replaces_its_landmark(min_views):
    """A false positive of a mapped class in the frame that sees the real one must not re-initialise the landmark
    there (it once took the class's slot and left the real landmark orphaned in the state)."""
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), SlamConfig.thesis(min_views=min_views))
    for _ in range(min_views):
        slam.update([Measurement(2.0, 0.1, "bp", 1.0, 0.05, 0.02)])
    mapped = slam.landmarks["bp"]
    for _ in range(3):
        log = slam.update([Measurement(2.0, 0.1, "bp", 1.0, 0.05, 0.02), Measurement(3.0, -0.5, "bp", 0.5, 0.05, 0.02)])
        assert log.accepted == ["bp"] and log.rejected == ["bp"]
    assert len(slam.mu) == 5 and list(slam.landmarks) == ["bp"]
    assert np.allclose(slam.landmarks["bp"], mapped, atol=0.01)


@pytest.mark.parametrize("n", [3, 5])
def test_minimal_view_delays_initialisation_by_exactly_n_sightings(n):
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), SlamConfig.thesis(min_views=n))
    for sighting in range(1, n + 1):
        log = slam.update([Measurement(2.0 + 0.01 * sighting, 0.1, "py", 1.0, 0.05, 0.02)])
        assert ("py" in slam.slots) == (sighting == n)
        assert log.initialised == (["py"] if sighting == n else []) and log.pending == ([] if sighting == n else ["py"])
    # A sighting far from the others restarts the count.
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), SlamConfig.thesis(min_views=3))
    for r in (2.0, 2.0, 4.0, 4.0):
        slam.update([Measurement(r, 0.1, "gp", 1.0, 0.05, 0.02)])
    assert "gp" not in slam.slots


def test_fej_is_more_consistent_than_classic_on_a_monte_carlo_run():
    """Huang et al.: the classic EKF's Jacobians gain spurious information, so its NEES exceeds FEJ's."""
    classic, fej = [], []
    for seed in range(8):
        sequence = walk_sequence(simulate(SimConfig(seed=seed, duration_s=90, false_positive_rate=0.0, miss_rate=0.0)))
        classic.append(run_slam(sequence, SlamConfig.thesis()).metrics()["nees"]["mean"])
        fej.append(run_slam(sequence, SlamConfig.thesis(linearisation="fej")).metrics()["nees"]["mean"])
    assert np.mean(fej) < np.mean(classic)


def test_odometry_drift_is_like_the_thesis():
    errors = [run_slam(walk_sequence(simulate(SimConfig(seed=s)))).metrics()["odometry_error"]["mean"]
              for s in range(6)]
    assert 0.3 < np.mean(errors) < 0.7


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
def test_localisation_on_a_known_map_tracks_the_circle(filter_class):
    walk = simulate(SimConfig(path="circle", seed=4, false_positive_rate=0.2))
    start = walk.steps[0].true_pose
    localiser = filter_class(start, np.eye(3) * 1e-3, walk.landmarks, OdometryModel())
    errors, odometry_errors = [], []
    for previous, step in zip(walk.steps, walk.steps[1:]):
        localiser.predict(OdometryModel.control(previous.odometry_pose, step.odometry_pose))
        if step.measurements:
            localiser.update(step.measurements)
        errors.append(np.linalg.norm(localiser.pose[:2] - step.true_pose[:2]))
        odometry_errors.append(np.linalg.norm(step.odometry_pose[:2] - step.true_pose[:2]))
    assert np.mean(errors) < 0.3 < np.mean(odometry_errors)


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
@pytest.mark.parametrize("gate", [0.0, -1.0, float("nan"), float("inf")])
def test_a_localiser_refuses_a_gate_that_would_turn_every_sighting_away(filter_class, gate):
    with pytest.raises(ValueError, match="must be a positive chi-square bound"):
        filter_class(np.zeros(3), np.eye(3) * 1e-3, {"bp": (1.0, 0.0)}, OdometryModel(), gate=gate)


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
def test_localisation_learns_a_misreported_stride(filter_class):
    """The sim's walk engine reports 1.25 times its stride and turns 4 % too far. The scales in the state settle on
    the true 0.8 and 1/1.04; the thesis's pose-only filter trusts the odometry and ends several times farther off."""
    walk = simulate(SimConfig(path="circle", seed=4, false_positive_rate=0.2))
    start = walk.steps[0].true_pose
    calibrated = filter_class(start, np.eye(3) * 1e-3, walk.landmarks, OdometryModel())
    pose_only = filter_class(start, np.eye(3) * 1e-3, walk.landmarks, OdometryModel(), odometry_scale_std=None)
    errors = {calibrated: [], pose_only: []}
    for previous, step in zip(walk.steps, walk.steps[1:]):
        for localiser, error in errors.items():
            localiser.predict(OdometryModel.control(previous.odometry_pose, step.odometry_pose))
            if step.measurements:
                localiser.update(step.measurements)
            error.append(np.linalg.norm(localiser.pose[:2] - step.true_pose[:2]))
    assert np.allclose(calibrated.odometry_scales, (1 / 1.25, 1 / 1.04), atol=0.03)
    assert pose_only.odometry_scales == (1.0, 1.0)
    assert np.mean(errors[calibrated]) < 0.1 and np.mean(errors[pose_only]) > 3 * np.mean(errors[calibrated])


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
def test_a_swapped_class_corrects_the_pose_only_where_one_landmark_explains_it(filter_class):
    """The detector names a green-band pole blue: with the gate, the one landmark that explains the sighting takes it
    (as in SLAM); with two landmarks of other classes inside the gate nothing is used; without a gate the class is
    the landmark, as in the thesis."""
    truth = np.array([0.1, 0.0, 0.0])
    landmarks = {"gp": (3.0, 1.0), "bp": (-3.0, 1.0), "yp": (3.0, 1.3)}
    seen_gp_as_bp = Measurement(*observation.expected(truth, np.array([3.0, 1.0])), "bp", 0.9, 0.05, 0.02)

    def localiser(names, **kwargs):
        return filter_class(np.zeros(3), np.eye(3) * 0.01, {n: landmarks[n] for n in names}, OdometryModel(), **kwargs)

    alone = localiser(("gp", "bp"))
    assert alone.update([seen_gp_as_bp]) == 1 and abs(alone.pose[0] - truth[0]) < 0.05
    assert localiser(("gp", "bp", "yp")).update([seen_gp_as_bp]) == 0
    thesis = localiser(("gp", "bp"), gate=None)
    assert thesis.update([seen_gp_as_bp]) == 1 and abs(thesis.pose[0] - truth[0]) > 0.05


def test_localisation_rows_run_only_where_the_start_is_a_true_pose_on_a_known_map():
    """A simulated walk starts at its true pose on its true map; a log whose start is its own origin (UTIAS without
    robot truth) or a recording without a map cannot be localised, and the comparison leaves those rows out."""
    from detector.slam.comparison import BACKENDS, compare_backends
    from naoslam.runner import LocalisationConfig, localisable

    walk = walk_sequence(simulate(SimConfig(duration_s=10, seed=1)))
    unmapped = replace(walk, landmarks_truth={})
    elsewhere = replace(walk, start=walk.start + np.array([1.0, 0.0, 0.0]))
    assert localisable(walk) and not localisable(unmapped) and not localisable(elsewhere)
    rows = compare_backends(lambda seed: elsewhere, [0], BACKENDS)
    assert [row.backend for row in rows] == [n for n, c in BACKENDS.items() if not isinstance(c, LocalisationConfig)]


def test_ekf_and_eif_agree_on_one_linear_step():
    landmarks = {"bp": (3.0, 1.0)}
    ekf = EkfLocalisation(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel(), gate=None)
    eif = EifLocalisation(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel(), gate=None)
    z = [Measurement(3.1, 0.33, "bp", 1.0, 0.05, 0.02)]
    for f in (ekf, eif):
        f.predict(np.array([0.0, 0.1, 0.0]))
        f.update(z)
    assert np.allclose(ekf.pose, eif.pose, atol=1e-9)
    assert np.allclose(np.linalg.inv(eif.omega), ekf.sigma, atol=1e-9)


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
def test_a_second_box_on_the_same_pole_adds_no_information(filter_class):
    """Two detections of one landmark in a frame: only the one nearer the prediction corrects the pose."""
    landmarks = {"bp": (3.0, 1.0)}
    right, second = Measurement(3.1, 0.33, "bp", 1.0, 0.05, 0.02), Measurement(3.25, 0.36, "bp", 0.6, 0.05, 0.02)
    once, twice = (filter_class(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel()) for _ in range(2))
    assert once.update([right]) == 1 and twice.update([second, right]) == 1
    assert np.array_equal(once.pose, twice.pose)


def test_a_slower_front_end_sees_every_nth_frame_of_the_same_walk():
    full = simulate(SimConfig(seed=3, duration_s=20))
    slow = simulate(SimConfig(seed=3, duration_s=20, front_end_hz=1.25))
    for a, b in zip(full.steps, slow.steps, strict=True):
        assert np.array_equal(a.true_pose, b.true_pose) and np.array_equal(a.odometry_pose, b.odometry_pose)
    framed = [i for i, step in enumerate(full.steps) if step.measurements is not None]
    assert [i for i, step in enumerate(slow.steps) if step.measurements is not None] == framed[::4]
    assert all(slow.steps[i].measurements == full.steps[i].measurements for i in framed[::4])
    with pytest.raises(ValueError, match="front_end_hz 2: give the camera's 5 Hz divided by a whole number"):
        SimConfig(front_end_hz=2.0)


def test_frames_merge_in_time_order_with_the_offset():
    controls = [Event(t, np.zeros(3)) for t in (0.0, 0.1, 0.2, 0.3)]
    frames = [Event(0.0, measurements=[]), Event(0.1, measurements=[])]
    merged = merge_frames(controls, frames, time_offset_s=0.15)
    assert [(e.t, e.measurements is not None) for e in merged] == [
        (0.0, False), (0.1, False), (0.15, True), (0.2, False), (0.25, True), (0.3, False)]


def test_the_runner_folds_in_empty_frames_as_a_robot_loop_does():
    """Two sightings, then 30 frames without detections: the candidate has expired (patience 25 frames) when the
    third sighting comes, in the runner as in a loop that calls ``update`` on every frame."""
    sighting = [Measurement(2.0, 0.1, "py", 1.0, 0.05, 0.02)]
    frames = [sighting, sighting] + [[]] * 30 + [sighting]
    sequence = Sequence([Event(0.2 * i, np.zeros(3), m) for i, m in enumerate(frames)], np.zeros(3), OdometryModel(),
                        {"py": (2.0, 0.2)})
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), SlamConfig())
    for measurements in frames:
        slam.predict(np.zeros(3))
        slam.update(measurements)
    assert not slam.landmarks and not run_slam(sequence, SlamConfig()).landmarks
    assert run_slam(replace(sequence, events=sequence.events[:2] + sequence.events[-1:]), SlamConfig()).landmarks


def test_se2_alignment_undoes_a_rigid_motion():
    rng = np.random.default_rng(0)
    truth = rng.uniform(-5, 5, (6, 2))
    angle = 0.7
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    moved = truth @ rotation.T + [1.5, -2.0]
    back, shift = fit_se2(moved, truth)
    assert np.allclose(moved @ back.T + shift, truth)


def _result_of_a_moved_map(true_poses: np.ndarray | None) -> tuple[SlamResult, dict]:
    """A run whose map is the truth turned by 0.7 rad, shifted, and one landmark 0.3 m off; poses on the map."""
    truth = {"1": (0.0, 0.0), "2": (4.0, 0.0), "3": (0.0, 3.0), "4": (4.0, 3.0)}
    angle, shift = 0.7, np.array([1.5, -2.0])
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    landmarks = {name: np.array(xy) @ rotation.T + shift for name, xy in truth.items()}
    landmarks["4"] = landmarks["4"] + [0.3, 0.0]
    poses = np.array([[*landmarks["1"], 0.0], [*landmarks["2"], 0.0]])
    return SlamResult("test", np.arange(2.0), poses, true_poses, None, landmarks, truth, None), truth


def test_a_map_without_robot_truth_is_drawn_with_the_fit_it_is_scored_after():
    result, truth = _result_of_a_moved_map(true_poses=None)
    rotation, translation = result.truth_alignment()
    moved = {name: xy @ rotation.T + translation for name, xy in result.landmarks.items()}
    errors = [np.linalg.norm(moved[name] - truth[name]) for name in truth]
    assert result.metrics()["landmark_error"]["mean"] == pytest.approx(np.mean(errors))
    assert np.allclose(moved["1"], truth["1"], atol=0.2) and np.mean(errors) < 0.15
    assert _result_of_a_moved_map(true_poses=np.zeros((2, 3)))[0].truth_alignment() is None


def test_utias_map_plot_shows_the_estimate_fitted_onto_the_truth(tmp_path, monkeypatch):
    import detector.slam.outputs
    from detector.slam.outputs import plot_map

    drawn = {}
    monkeypatch.setattr(detector.slam.outputs, "save_figure", lambda fig, png: drawn.setdefault("axes", fig.axes[0]))
    result, truth = _result_of_a_moved_map(true_poses=None)
    plot_map(result, tmp_path / "map.png", "moved")
    by_label = {c.get_label(): c.get_offsets() for c in drawn["axes"].collections}
    crosses = by_label["estimated landmarks (fitted onto the truth)"]
    assert np.abs(crosses[:3] - np.array([truth[name] for name in "123"])).max() < 0.2


def test_utias_loader_parses_the_shared_log():
    folder = SHARED / "utias-mrclam" / "dataset0"
    if not folder.is_dir():
        pytest.skip("../shared/utias-mrclam is not on this machine")
    sequence = load_utias(folder, duration_s=120)
    frames = [e for e in sequence.events if e.measurements]
    assert len(sequence.landmarks_truth) == 15 and frames
    assert all(m.signature in sequence.landmarks_truth for e in frames for m in e.measurements)
    assert all(a.t <= b.t for a, b in zip(sequence.events, sequence.events[1:]))
    metrics = run_slam(sequence, SlamConfig(association="class")).metrics()
    assert "robot_error" not in metrics and metrics["landmark_error"]["aligned"]


def test_utias_loader_names_a_bad_line(tmp_path):
    for name in ("Odometry.dat", "Barcodes.dat", "Landmark_Groundtruth.dat"):
        (tmp_path / name).write_text("# header\n1 2 3\n2 2 3\n")
    (tmp_path / "Measurement.dat").write_text("# header\n1.0 5 far 0.1\n")
    with pytest.raises(ValueError, match=r"Measurement.dat:2"):
        load_utias(tmp_path)


def test_a_utias_log_is_cut_at_the_duration_asked_and_a_duration_of_0_is_refused(tmp_path):
    """``--duration 0`` ran the whole log and ``--duration -5`` ended in an IndexError."""
    (tmp_path / "Odometry.dat").write_text("# t v w\n" + "".join(f"{t} 0.1 0.0\n" for t in range(10, 20)))
    (tmp_path / "Measurement.dat").write_text("# t barcode r b\n12 5 1.0 0.1\n18 5 1.0 0.1\n")
    (tmp_path / "Barcodes.dat").write_text("# subject barcode\n6 5\n")
    (tmp_path / "Landmark_Groundtruth.dat").write_text("# subject x y\n6 1.0 0.0\n")
    def controls_and_frames(sequence: Sequence) -> tuple[list[float], list[float]]:
        return ([e.t for e in sequence.events if e.measurements is None],
                [e.t for e in sequence.events if e.measurements is not None])

    assert controls_and_frames(load_utias(tmp_path)) == ([float(t) for t in range(9)], [2.0, 8.0])
    assert controls_and_frames(load_utias(tmp_path, duration_s=4)) == ([0.0, 1.0, 2.0, 3.0], [2.0])
    for duration in (0.0, -5.0, math.nan):
        with pytest.raises(ValueError, match="must be a positive number of seconds"):
            load_utias(tmp_path, duration_s=duration)


def test_the_parent_of_utias_logs_is_refused_naming_the_logs_inside(tmp_path):
    for log in ("dataset1", "dataset0"):
        for name in ("Odometry.dat", "Measurement.dat", "Barcodes.dat", "Landmark_Groundtruth.dat"):
            (tmp_path / log).mkdir(exist_ok=True)
            (tmp_path / log / name).write_text("# header\n")
    (tmp_path / "notes").mkdir()
    with pytest.raises(FileNotFoundError, match=r"missing Odometry.dat.* - pass the folder of one log: dataset0, dataset1$"):
        load_utias(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"missing Odometry.dat, Measurement.dat, Barcodes.dat, Landmark_Groundtruth.dat$"):
        load_utias(tmp_path / "notes")


def test_optitrack_reader_gives_planar_pose(tmp_path):
    csv = tmp_path / "take.csv"
    s = math.sin(math.radians(30) / 2)
    c = math.cos(math.radians(30) / 2)
    csv.write_text("Format Version,1.23\n\n"
                   ",,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body\n"
                   ",,NAO,NAO,NAO,NAO,NAO,NAO,NAO\n"
                   ",,1,1,1,1,1,1,1\n"
                   ",,Rotation,Rotation,Rotation,Rotation,Position,Position,Position\n"
                   "Frame,Time (Seconds),X,Y,Z,W,X,Y,Z\n"
                   f"0,0.0,0,{s},0,{c},1.0,0.3,-2.0\n")
    rows = load_optitrack(csv)
    assert rows.shape == (1, 4) and np.allclose(rows[0, :3], [0.0, 1.0, 2.0])
    assert math.degrees(rows[0, 3]) == pytest.approx(30.0)


def test_runtime_imports_no_training_libraries():
    code = ("import sys, naoslam.ekf_slam, naoslam.localisation, naoslam.sim, naoslam.logs, naoslam.runner, "
            "naoslam.perception.colour_filter, naoslam.measurement; "
            "bad = [m for m in ('torch', 'ultralytics', 'albumentations', 'detector') if m in sys.modules]; "
            "sys.exit(1 if bad else 0)")
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def _filters() -> dict:
    landmarks = {"bp": (2.0, 0.5), "yp": (1.5, -1.0)}
    return {"ekf slam": EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel()),
            "ekf localisation": EkfLocalisation(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel()),
            "eif localisation": EifLocalisation(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel())}


@pytest.mark.parametrize("name", ["ekf slam", "ekf localisation", "eif localisation"])
@pytest.mark.parametrize("control", [[math.nan, 0.1, 0.0], [0.0, math.inf, 0.0], [0.0, 0.1]])
def test_a_control_that_is_not_finite_is_refused_and_the_filter_runs_on(name, control):
    """One NaN from an odometry glitch used to turn the pose and covariance into NaN for good."""
    slam = _filters()[name]
    slam.predict(np.array([0.1, 0.2, 0.0]))
    before = {k: np.copy(v) for k, v in vars(slam).items() if isinstance(v, np.ndarray)}
    with pytest.raises(ValueError, match="not three finite numbers"):
        slam.predict(np.array(control))
    assert all(np.array_equal(before[k], getattr(slam, k)) for k in before)
    slam.predict(np.array([0.0, 0.2, 0.0]))
    x, y, heading = 0.4 * math.cos(0.1), 0.4 * math.sin(0.1), 0.1  # the two good steps, as dead reckoning
    assert np.allclose(slam.pose, (x, y, heading))
    seen = Measurement(math.hypot(2.0 - x, 0.5 - y), math.atan2(0.5 - y, 2.0 - x) - heading, "bp", 0.9, 0.1, 0.02)
    slam.update([seen])
    assert np.allclose(slam.pose, (x, y, heading), atol=1e-3)


@pytest.mark.parametrize("values", [(math.nan, 0.1, 0.1, 0.02), (2.0, math.inf, 0.1, 0.02), (0.0, 0.1, 0.1, 0.02),
                                    (2.0, 0.1, -0.1, 0.02), (2.0, 0.1, 0.1, math.nan)])
def test_a_measurement_that_is_not_finite_or_has_no_range_is_refused(values):
    range_m, bearing, range_std, bearing_std = values
    with pytest.raises(ValueError, match="the range must be positive, the noise not negative, all four finite"):
        Measurement(range_m, bearing, "bp", 0.9, range_std, bearing_std)


@pytest.mark.parametrize("kwargs, message", [({"duration_s": float("inf")}, "duration_s inf must be a positive finite"),
                                             ({"stride_scale": float("nan")}, "stride_scale nan must be a positive"),
                                             ({"lookalikes": -1}, "lookalikes -1 must be 0 or more")])
def test_a_walk_names_the_setting_it_cannot_simulate(kwargs, message):
    """An infinite walk ended in an OverflowError, an odometry bias of nan in a complaint about the first control."""
    with pytest.raises(ValueError, match=message):
        SimConfig(**kwargs)


@pytest.mark.parametrize("pose, cov, message", [
    (np.array([math.nan, 0.0, 0.0]), np.eye(3) * 1e-4, "start pose .* is not three finite numbers"),
    (np.zeros(2), np.eye(3) * 1e-4, "start pose .* is not three finite numbers"),
    (np.zeros(3), np.eye(2) * 1e-4, "start covariance of shape \\(2, 2\\)"),
    (np.zeros(3), -np.eye(3) * 1e-4, "no negative variance"),
    (np.zeros(3), np.array([[1e-4, 1e-3, 0.0], [0.0, 1e-4, 0.0], [0.0, 0.0, 1e-4]]), "not a symmetric")])
@pytest.mark.parametrize("make", [lambda p, c: EkfSlam(p, c, OdometryModel()),
                                  lambda p, c: EkfLocalisation(p, c, {"bp": (1.0, 0.0)}, OdometryModel()),
                                  lambda p, c: EifLocalisation(p, c, {"bp": (1.0, 0.0)}, OdometryModel())],
                         ids=["ekf slam", "ekf localisation", "eif localisation"])
def test_a_start_that_is_not_one_is_refused_before_the_filter_runs(make, pose, cov, message):
    """A NaN start pose or a negative variance was taken as given and spread to every estimate."""
    with pytest.raises(ValueError, match=message):
        make(pose, cov)


@pytest.mark.parametrize("landmarks, message", [({}, "the map holds no pole"),
                                                ({"bp": (math.nan, 0.0)}, "map pole 'bp'"),
                                                ({"bp": (1.0, 0.0, 0.0)}, "two finite numbers")])
def test_a_localisation_map_that_is_not_one_is_refused(landmarks, message):
    """An empty map left the localiser to follow the odometry without a word."""
    with pytest.raises(ValueError, match=message):
        EkfLocalisation(np.zeros(3), np.eye(3) * 1e-4, landmarks, OdometryModel())


def test_the_information_filter_needs_a_start_it_can_invert_and_noise_is_never_negative():
    EkfLocalisation(np.zeros(3), np.zeros((3, 3)), {"bp": (1.0, 0.0)}, OdometryModel())  # a known start: fine
    with pytest.raises(ValueError, match="every variance above 0"):
        EifLocalisation(np.zeros(3), np.zeros((3, 3)), {"bp": (1.0, 0.0)}, OdometryModel())
    for model in (OdometryModel, VelocityModel):
        with pytest.raises(ValueError, match="none negative"):
            model(alphas=(-0.1, 0.0, 0.0, 0.0))


def _maybe(range_m: float, bearing: float, cls: str) -> Measurement:
    """A tentative sighting: below the operating threshold."""
    return Measurement(range_m, bearing, cls, 0.4, 0.05, 0.02, tentative=True)


@pytest.mark.parametrize("association", ["nearest", "class"])
def test_a_maybe_confirms_a_mapped_landmark_of_its_class_inside_the_gate_and_nothing_else(association):
    slam = _mapped_slam(SlamConfig(min_views=1, association=association))
    before = slam.sigma.copy()
    log = slam.update([_maybe(2.01, 0.1, "bp")])  # where the mapped bp is: it confirms it
    assert log.accepted == ["bp"] and np.trace(slam.sigma) < np.trace(before)
    for wrong in (_maybe(2.0, 0.1, "gp"), _maybe(3.5, -0.6, "bp"), _maybe(1.5, 1.2, "py")):  # class, gate, new
        state = (slam.mu.copy(), slam.sigma.copy())
        log = slam.update([wrong])
        assert log.unconfirmed + log.rejected == [wrong.signature] and not log.initialised and not log.pending
        assert np.array_equal(slam.mu, state[0]) and np.array_equal(slam.sigma, state[1])
    assert list(slam.landmarks) == ["bp"] and len(slam.mu) == slam.robot_size + 2


def test_a_maybe_never_starts_a_landmark_however_often_it_is_seen():
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), SlamConfig(min_views=2))
    for _ in range(5):
        assert slam.update([_maybe(2.0, 0.1, "bp")]).unconfirmed == ["bp"]
    assert not slam.slots


@pytest.mark.parametrize("filter_class", [EkfLocalisation, EifLocalisation])
def test_a_localiser_takes_a_maybe_only_for_the_landmark_of_its_class(filter_class):
    truth = np.array([0.1, 0.0, 0.0])
    landmarks = {"gp": (3.0, 1.0), "bp": (-3.0, 1.0)}
    seen = observation.expected(truth, np.array([3.0, 1.0]))
    localiser = filter_class(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel())
    assert localiser.update([Measurement(*seen, "bp", 0.4, 0.05, 0.02, tentative=True)]) == 0  # another class
    assert localiser.update([Measurement(*seen, "gp", 0.4, 0.05, 0.02, tentative=True)]) == 1
    thesis = filter_class(np.zeros(3), np.eye(3) * 0.01, landmarks, OdometryModel(), gate=None)
    assert thesis.update([Measurement(*seen, "gp", 0.4, 0.05, 0.02, tentative=True)]) == 0  # no gate, no maybe
