"""The robust default back end: odometry self-calibration, delayed initialisation, class-tolerant association,
OC-EKF, honest scoring, the simulator's hard cases and the GTSAM smoother reference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from naoslam.association import CandidatePool, Hypothesis, choose
from naoslam.ekf_slam import EkfSlam, SlamConfig, _observable_part
from naoslam.measurement import Measurement
from naoslam.metrics import chi2_band
from naoslam.motion import OdometryModel
from naoslam.observation import jacobians
from naoslam.runner import run_slam, score_map, walk_sequence
from naoslam.sim import CONFUSED_SOURCE, LOOKALIKE_SOURCE, SimConfig, simulate


def _runs(seeds, **sim) -> list[dict]:
    return [run_slam(walk_sequence(simulate(SimConfig(seed=s, **sim)))).metrics() for s in seeds]


def test_the_default_recovers_the_odometry_bias_and_beats_odometry_without_phantoms():
    runs = _runs(range(3))
    for metrics in runs:
        assert metrics["odometry_scales"]["stride"] == pytest.approx(1 / 1.25, abs=0.03)
        assert metrics["odometry_scales"]["turn"] == pytest.approx(1 / 1.04, abs=0.02)
        assert not metrics["phantoms"] and not metrics["landmarks_missing"]
        assert metrics["nees"]["mean"] < chi2_band(3)[1]
    assert np.mean([m["landmark_error"]["mean"] for m in runs]) < 0.2
    assert np.mean([m["robot_error"]["mean"] for m in runs]) < 0.15 < np.mean([m["odometry_error"]["mean"]
                                                                              for m in runs])


def test_the_thesis_ekf_is_over_confident_on_the_same_walks():
    """Raw biased odometry and no gate: the NEES explodes (the failure the default fixes)."""
    sequence = walk_sequence(simulate(SimConfig(seed=0)))
    assert run_slam(sequence, SlamConfig.thesis()).metrics()["nees"]["mean"] > 10 * chi2_band(3)[1]


def test_confusions_and_a_persistent_lookalike_do_not_break_the_map():
    runs = _runs(range(3), confusion_rate=0.1, lookalikes=1)
    for metrics in runs:
        assert metrics["counts"]["confused"] > 0
        assert not metrics["landmarks_missing"] and len(metrics["phantoms"]) <= 1
    assert np.mean([m["landmark_error"]["mean"] for m in runs]) < 0.3
    assert np.mean([m["robot_error"]["mean"] for m in runs]) < 0.2


def _mapped(config: SlamConfig = SlamConfig(), views: int = 3) -> EkfSlam:
    slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-4, OdometryModel(), config)
    for _ in range(views):
        slam.update([Measurement(2.0, 0.1, "bp", 1.0, 0.05, 0.02)])
    return slam


def test_a_single_false_positive_never_enters_the_map():
    slam = _mapped()
    assert set(slam.landmarks) == {"bp"}
    sighting = Measurement(3.0, -0.4, "gp", 0.9, 0.15, 0.02)
    for _ in range(2):
        log = slam.update([sighting])
        assert log.pending == ["gp"] and set(slam.landmarks) == {"bp"}
    for _ in range(30):  # the candidate expires unless seen again soon
        slam.update([])
    assert slam.update([sighting]).pending == ["gp"]
    assert slam.update([sighting]).pending == ["gp"] and slam.update([sighting]).initialised == ["gp"]


@pytest.mark.parametrize("separation, mapped", [(0.5, {"bp"}), (0.0, {"bp", "gp"})])
def test_a_second_box_on_a_mapped_pole_never_becomes_a_landmark(separation, mapped):
    """The detector's second box of another class on the same pole: the pole's landmark is taken by the first box,
    so no gate explains the second; only the separation rule keeps it from starting a phantom beside the pole."""
    slam = _mapped(SlamConfig(min_separation_m=separation))
    boxes = [Measurement(2.0, 0.1, "bp", 0.9, 0.05, 0.02), Measurement(2.1, 0.11, "gp", 0.6, 0.05, 0.02)]
    logs = [slam.update(boxes) for _ in range(5)]
    assert all(log.accepted[0] == "bp" for log in logs)
    assert set(slam.landmarks) == mapped


def test_a_pole_a_metre_from_a_landmark_still_enters_the_map():
    slam = _mapped()
    biased = Measurement(2.3, 0.1, "bp", 0.9, 0.02, 0.01)  # 0.3 m beyond the landmark, 15 sigma out: never mapped
    beside = Measurement(2.9, 0.1, "bp", 0.9, 0.02, 0.01)  # 0.9 m beyond: another pole
    assert [slam.update([biased]).rejected for _ in range(4)] == [["bp"]] * 4
    assert [slam.update([beside]).initialised for _ in range(3)] == [[], [], ["bp"]]
    assert len(slam.landmarks) == 2


def test_a_confused_class_updates_the_only_landmark_in_the_gate():
    slam = _mapped()
    log = slam.update([Measurement(2.02, 0.1, "gp", 0.9, 0.05, 0.02)])
    assert log.confused == ["gp"] and set(slam.landmarks) == {"bp"}
    known = _mapped(SlamConfig(association="class"))
    assert known.update([Measurement(2.02, 0.1, "gp", 0.9, 0.05, 0.02)]).pending == ["gp"]


def test_association_prefers_the_class_and_rejects_ambiguity():
    both = [Hypothesis("a", "bp", 3.0), Hypothesis("b", "gp", 1.0)]
    assert choose(both, "bp", 9.21) == ("a", "match")
    assert choose(both, "yp", 9.21) == (None, "ambiguous")
    assert choose([Hypothesis("a", "bp", 20.0)], "bp", 9.21) == (None, "ambiguous")  # just outside its own gate
    assert choose([Hypothesis("a", "bp", 200.0)], "bp", 9.21) == (None, "new")


def test_a_candidate_needs_agreeing_sightings():
    pool = CandidatePool(min_views=3)
    spread = np.eye(2) * 0.01
    assert pool.sighting(np.array([1.0, 1.0]), spread, "py", 1) is None
    assert pool.sighting(np.array([3.0, 1.0]), spread, "py", 2) is None  # 20 sigma away: a second candidate
    assert pool.sighting(np.array([1.05, 1.0]), spread, "yp", 3) is None
    assert pool.sighting(np.array([0.95, 1.02]), spread, "py", 4) == "py"  # majority class of the three


def test_oc_ekf_jacobian_is_blind_to_the_unobservable_directions():
    pose, landmark = np.array([0.4, -1.0, 0.3]), np.array([2.0, 1.5])
    h = _observable_part(np.hstack(jacobians(pose, landmark)), pose, landmark)
    u = np.array([[1, 0, -pose[1]], [0, 1, pose[0]], [0, 0, 1], [1, 0, -landmark[1]], [0, 1, landmark[0]]])
    assert np.allclose(h @ u, 0.0, atol=1e-12)
    assert np.linalg.matrix_rank(h) == 2


def test_joseph_update_keeps_the_covariance_positive_definite_with_tiny_noise():
    slam = _mapped(views=3)
    for _ in range(200):
        slam.predict(np.array([0.0, 0.0, 0.0]))
        slam.update([Measurement(2.0, 0.1, "bp", 1.0, 1e-6, 1e-7)])
    assert np.array_equal(slam.sigma, slam.sigma.T) and np.linalg.eigvalsh(slam.sigma).min() > -1e-12


@pytest.mark.parametrize("dof, runs", [(1, 1), (2, 1), (3, 1), (3, 10), (5, 4)])
def test_chi_square_band_matches_scipy(dof, runs):
    low, high = chi2_band(dof, runs)
    assert low == pytest.approx(chi2.ppf(0.025, dof * runs) / runs, rel=1e-6)
    assert high == pytest.approx(chi2.ppf(0.975, dof * runs) / runs, rel=1e-6)


def test_scoring_reports_missing_landmarks_and_phantoms():
    truth = {"bp": (0.0, 0.0), "gp": (5.0, 0.0)}
    mapped = {"bp": np.array([0.1, 0.0]), "bp#2": np.array([3.0, 0.0]), "yp": np.array([9.0, 0.0])}
    report = score_map(mapped, truth, align=False)
    assert report["landmarks_missing"] == ["gp"]
    assert report["landmark_error"]["mean"] == pytest.approx(0.1) and report["landmark_error"]["of"] == 2
    assert report["phantoms"] == pytest.approx({"bp#2": 2.0, "yp": 4.0})


def test_the_simulator_tags_lookalikes_and_confusions_and_reports_noise_from_the_measured_range():
    walk = simulate(SimConfig(seed=1, confusion_rate=0.2, lookalikes=2))
    sightings = [m for step in walk.steps for m in step.measurements or []]
    sources = {m.source for m in sightings}
    assert LOOKALIKE_SOURCE in sources and any(s.startswith(CONFUSED_SOURCE) for s in sources)
    assert len(walk.lookalikes) == 2
    for m in sightings:
        if m.source.startswith(CONFUSED_SOURCE):
            assert m.signature != m.source[len(CONFUSED_SOURCE):]
        assert m.range_std == pytest.approx(walk.config.range_rel_std * m.range_m)


def test_the_smoother_reference_recovers_the_scales_and_beats_odometry():
    pytest.importorskip("gtsam")
    from detector.slam.reference import smooth

    metrics = smooth(walk_sequence(simulate(SimConfig(seed=2, lookalikes=1, confusion_rate=0.1)))).metrics()
    assert metrics["odometry_scales"]["stride"] == pytest.approx(0.8, abs=0.03)
    assert metrics["landmark_error"]["mean"] < 0.2 and metrics["robot_error"]["mean"] < 0.1
    assert not metrics["phantoms"] and not metrics["landmarks_missing"]
