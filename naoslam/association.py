"""Which mapped landmark a detection belongs to, and when an unexplained detection becomes a new landmark.

A detection's class is evidence, not identity (the detector confuses green bands, a look-alike can carry any
class). Association is by geometry: nearest neighbour inside a Mahalanobis gate, the detected class preferred,
another class accepted only when it is the only landmark inside the gate. A detection that no landmark explains
joins a candidate; a candidate becomes a landmark when ``min_views`` sightings agree on its position (delayed
initialisation), so a one-off false positive never enters the map.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from naoslam.observation import CHI2_2DOF_99


@dataclass(frozen=True)
class Hypothesis:
    """One mapped landmark as an explanation of a detection: its id, majority class and squared Mahalanobis distance."""

    landmark: str
    label: str
    distance2: float


#: A detection outside every gate starts a candidate only if no landmark of its class lies within this many times
#: the gate: just outside its own landmark's gate it is more likely a bad measurement than a second pole.
NEW_LANDMARK_MARGIN = 4.0


def choose(hypotheses: list[Hypothesis], detected: str, gate: float) -> tuple[str | None, str]:
    """(landmark, verdict) for one detection; verdict is ``match``, ``confused``, ``ambiguous`` or ``new``.

    ``match``: the nearest landmark of the detected class inside the gate. ``confused``: no landmark of that class
    is inside, but exactly one of another class is. ``ambiguous`` (rejected): several of other classes are, or none
    is but a landmark of the detected class lies just outside. ``new``: the detection may start a landmark.
    """
    inside = sorted((h for h in hypotheses if h.distance2 <= gate), key=lambda h: h.distance2)
    same = [h for h in inside if h.label == detected]
    if same:
        return same[0].landmark, "match"
    if len(inside) == 1:
        return inside[0].landmark, "confused"
    near_own = any(h.label == detected and h.distance2 <= NEW_LANDMARK_MARGIN * gate for h in hypotheses)
    return (None, "ambiguous") if inside or near_own else (None, "new")


@dataclass(eq=False)
class Candidate:
    """Sightings not yet explained by the map that agree on one position (information-weighted mean)."""

    information: np.ndarray
    weighted_sum: np.ndarray
    votes: Counter = field(default_factory=Counter)
    views: int = 0
    last_frame: int = 0

    @property
    def position(self) -> np.ndarray:
        return np.linalg.solve(self.information, self.weighted_sum)

    def agrees(self, position: np.ndarray, covariance: np.ndarray, gate: float) -> bool:
        """True when a sighting lies within the Mahalanobis ``gate`` of this candidate."""
        difference = position - self.position
        spread = covariance + np.linalg.inv(self.information) + np.eye(2) * 1e-12
        return float(difference @ np.linalg.solve(spread, difference)) <= gate

    def add(self, position: np.ndarray, covariance: np.ndarray, label: str, frame: int) -> None:
        """Fuse one sighting (information form) and count its class vote."""
        information = np.linalg.inv(covariance + np.eye(2) * 1e-12)
        self.information = self.information + information
        self.weighted_sum = self.weighted_sum + information @ position
        self.votes[label] += 1
        self.views += 1
        self.last_frame = frame


class CandidatePool:
    """Delayed initialisation: candidates that expire when not seen again within ``patience`` frames."""

    def __init__(self, min_views: int, gate: float = CHI2_2DOF_99, patience: int = 25):
        self.min_views = min_views
        self.gate = gate
        self.patience = patience
        self.candidates: list[Candidate] = []

    def sighting(self, position: np.ndarray, covariance: np.ndarray, label: str, frame: int) -> str | None:
        """Add one sighting; the majority class when its candidate reaches ``min_views`` (the candidate is then
        consumed), else None."""
        self.candidates = [c for c in self.candidates if frame - c.last_frame <= self.patience]
        agreeing = [c for c in self.candidates if c.agrees(position, covariance, self.gate)]
        if agreeing:
            candidate = min(agreeing, key=lambda c: float(np.sum((c.position - position) ** 2)))
        else:
            candidate = Candidate(np.zeros((2, 2)), np.zeros(2))
            self.candidates.append(candidate)
        candidate.add(position, covariance, label, frame)
        if candidate.views < self.min_views:
            return None
        self.candidates.remove(candidate)
        return candidate.votes.most_common(1)[0][0]
