"""The headline figures of one SLAM run, read once from the runtime's metrics (``SlamResult.metrics``, the content of
``poles slam``'s metrics.json): mean errors against the truth, missing and phantom landmarks, consistency."""
from __future__ import annotations

from dataclasses import dataclass

from detector.records import JsonRecord


@dataclass(frozen=True)
class RunFigures(JsonRecord):
    """Mean robot, landmark and odometry-alone errors (m; None without the truth to score them), landmarks missed and
    phantoms mapped, mean NEES and NIS, sightings accepted and landmarks initialised."""

    robot_error: float | None
    landmark_error: float | None
    odometry_error: float | None
    missing: int
    phantoms: int
    nees: float | None
    nis: float | None
    accepted: int
    initialised: int

    @classmethod
    def of(cls, metrics: dict) -> RunFigures:
        """The figures of one run's metrics (``SlamResult.metrics()``)."""
        def mean(key: str) -> float | None:
            return metrics[key]["mean"] if key in metrics else None

        return cls(mean("robot_error"), mean("landmark_error"), mean("odometry_error"),
                   len(metrics.get("landmarks_missing", [])), len(metrics.get("phantoms", {})), mean("nees"),
                   mean("nis"), metrics["counts"].get("accepted", 0), metrics["counts"].get("initialised", 0))

    def errors(self) -> dict[str, float]:
        """The errors there was truth for, by name (robot, landmark, odometry alone)."""
        named = {"robot": self.robot_error, "landmark": self.landmark_error, "odometry alone": self.odometry_error}
        return {name: value for name, value in named.items() if value is not None}
