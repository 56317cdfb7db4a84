"""Time per predict and per update: EKF SLAM against the map size, and EKF vs EIF localisation against the number
of landmarks seen per step (the 2018 thesis's question: from how many does the EIF's cheaper correction win?).
Usage: python benchmarks/bench_filters.py [REPEATS]
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from naoslam.ekf_slam import EkfSlam, SlamConfig
from naoslam.localisation import EifLocalisation, EkfLocalisation
from naoslam.measurement import Measurement
from naoslam.motion import OdometryModel

U = np.array([0.05, 0.2, -0.03])


def _landmarks(n: int, rng: np.random.Generator) -> dict[str, tuple[float, float]]:
    return {f"L{i}": (float(x), float(y)) for i, (x, y) in enumerate(rng.uniform(-4, 4, (n, 2)))}


def _measurements(pose: np.ndarray, landmarks: dict[str, tuple[float, float]]) -> list[Measurement]:
    out = []
    for name, (x, y) in landmarks.items():
        r = math.hypot(x - pose[0], y - pose[1])
        out.append(Measurement(r, math.atan2(y - pose[1], x - pose[0]) - pose[2], name, 1.0, 0.05 * r + 0.01, 0.03))
    return out


def _median_ms(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def slam_scaling(repeats: int) -> None:
    """Known correspondences (the thesis's) and the default nearest-neighbour association, which computes a
    Mahalanobis distance to every mapped landmark for each detection."""
    rng = np.random.default_rng(0)
    print("EKF SLAM, one landmark corrected per update:")
    base = None
    for n in (6, 25, 50, 100, 200):
        landmarks = _landmarks(n, rng)
        row = []
        for config in (SlamConfig.thesis(), SlamConfig(min_views=1)):
            slam = EkfSlam(np.zeros(3), np.eye(3) * 1e-3, OdometryModel(), config)
            slam.update(_measurements(slam.pose, landmarks))
            one = _measurements(slam.pose, dict([next(iter(landmarks.items()))]))
            row += [_median_ms(lambda: slam.predict(U), repeats), _median_ms(lambda: slam.update(one), repeats)]
        base = base or row
        print(f"  {n:4d} landmarks: known correspondences predict {row[0]:.3f} ms (x{row[0] / base[0]:.1f} vs 6), "
              f"update {row[1]:.3f} ms (x{row[1] / base[1]:.1f}); default (scales, OC, NN association) predict "
              f"{row[2]:.3f} ms, update {row[3]:.3f} ms (x{row[3] / row[1]:.1f} of known correspondences)")


def localisation(repeats: int) -> None:
    """The thesis's pose-only state with known correspondences, and the default (odometry scales in the state,
    association by geometry inside the gate)."""
    for title, options in (("pose only, known correspondences (the 2018 thesis's)",
                            {"gate": None, "odometry_scale_std": None}),
                           ("default: odometry scales in the state, gated association", {})):
        rng = np.random.default_rng(1)
        print(f"Localisation on a known map, {title}, time per step against landmarks seen per step:")
        for k in (1, 2, 5, 10, 20, 50, 200):
            landmarks = _landmarks(k, rng)
            z = _measurements(np.zeros(3), landmarks)
            row = {}
            for name, cls in (("EKF", EkfLocalisation), ("EIF", EifLocalisation)):
                f = cls(np.zeros(3), np.eye(3) * 1e-2, landmarks, OdometryModel(), **options)
                row[name] = (_median_ms(lambda: f.predict(np.zeros(3)), repeats),
                             _median_ms(lambda: f.update(z), repeats))
            (ep, ec), (ip, ic) = row["EKF"], row["EIF"]
            print(f"  {k:4d} seen: EKF predict {ep:.3f} + correct {ec:.3f} = {ep + ec:.3f} ms | EIF predict {ip:.3f} "
                  f"+ correct {ic:.3f} = {ip + ic:.3f} ms | EIF/EKF {(ip + ic) / (ep + ec):.2f}")


if __name__ == "__main__":
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    slam_scaling(count)
    localisation(count)
