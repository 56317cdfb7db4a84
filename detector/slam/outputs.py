"""What a ``poles slam`` run writes: metrics.json, map.json, path.csv, and the map and error plots."""
from __future__ import annotations

import csv
import textwrap
from pathlib import Path

import numpy as np

from detector.atomic import atomic_path
from detector.formats import write_record
from detector.figures import plt, save_figure
from detector.slam.figures import RunFigures
from naoslam.runner import Sequence, SlamResult


def write_outputs(result: SlamResult, sequence: Sequence, out: Path) -> RunFigures:
    """metrics.json, path.csv, map.json (the map estimated, or a localiser's given map) and the two plots in ``out``;
    returns the run's headline figures."""
    out.mkdir(parents=True, exist_ok=True)
    metrics = {"sequence": sequence.name, **result.metrics()}
    write_record(out / "metrics.json", "slam", metrics)
    write_record(out / "map.json", "slam map",
                 {"landmarks": {k: [float(v[0]), float(v[1])] for k, v in result.landmarks.items()}})
    with atomic_path(out / "path.csv") as tmp:
        with tmp.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["t", "x", "y", "theta"] + (["true_x", "true_y", "true_theta"]
                                                        if result.true_poses is not None else []))
            for i, t in enumerate(result.times):
                extra = list(result.true_poses[i]) if result.true_poses is not None else []
                writer.writerow([f"{t:.3f}", *(f"{v:.4f}" for v in result.poses[i]), *(f"{v:.4f}" for v in extra)])
    plot_map(result, out / "map.png", sequence.name)
    if result.true_poses is not None:
        plot_errors(result, out / "errors.png")
    return RunFigures.of(metrics)


#: A map's title wraps at this many characters, so the back end's long label stays inside the 7-inch figure.
MAP_TITLE_CHARS = 90


def plot_map(result: SlamResult, png: Path, title: str) -> Path:
    """True and estimated landmarks and paths (and odometry), like the thesis's map figures. A run without robot
    truth (a UTIAS log) is drawn moved by the rigid fit of its map onto the true landmarks, the one its landmark
    error is scored after."""
    alignment = result.truth_alignment()
    rotation, translation = alignment if alignment else (np.eye(2), np.zeros(2))
    moved = " (fitted onto the truth)" if alignment else ""
    fig, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    if result.true_poses is not None:
        ax.plot(result.true_poses[:, 0], result.true_poses[:, 1], color="black", linewidth=1, label="true path")
    if result.odometry_poses is not None:
        ax.plot(result.odometry_poses[:, 0], result.odometry_poses[:, 1], color="grey", linestyle=":",
                label="odometry")
    path = result.poses[:, :2] @ rotation.T + translation
    ax.plot(path[:, 0], path[:, 1], color="tab:blue", linewidth=1, label=f"estimated path{moved}")
    truth = result.landmarks_truth
    if truth:
        ax.scatter(*np.array(list(truth.values())).T, marker="s", s=50, facecolors="none", edgecolors="black",
                   label="true landmarks")
    if result.landmarks:
        estimated = np.array(list(result.landmarks.values())) @ rotation.T + translation
        ax.scatter(*estimated.T, marker="x", s=50, color="tab:red",
                   label=f"estimated landmarks{moved}" if result.mapped else "the map it localised on")
        for name, (x, y) in zip(result.landmarks, estimated):
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(textwrap.fill(f"{result.label} - {title}", MAP_TITLE_CHARS), fontsize=9)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1))  # outside: never over a landmark
    ax.grid(alpha=0.3)
    return save_figure(fig, png)


def plot_errors(result: SlamResult, png: Path) -> Path:
    """Robot position error over time for the filter and for odometry alone."""
    fig, ax = plt.subplots(figsize=(7, 3), constrained_layout=True)
    ax.plot(result.times, np.linalg.norm(result.poses[:, :2] - result.true_poses[:, :2], axis=1), label=result.label)
    if result.odometry_poses is not None:
        ax.plot(result.times, np.linalg.norm(result.odometry_poses[:, :2] - result.true_poses[:, :2], axis=1),
                color="grey", linestyle=":", label="odometry alone")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("robot position error (m)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return save_figure(fig, png)
