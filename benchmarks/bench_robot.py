"""The robot budget: each front end's whole run per 640x480 frame, one thread, everything it runs capped at the Nao
v6's instruction set, and uncapped beside it.

The Atom E3845 has SSE4.2 and no AVX. Three libraries dispatch on the instruction set, and each is capped in a fresh
process before it loads: OpenVINO's CPU plugin (oneDNN) by ``ONEDNN_MAX_CPU_ISA=SSE41``, numpy by
``NPY_DISABLE_CPU_FEATURES`` (its AVX2 and AVX-512 dispatch targets), OpenCV by ``OPENCV_CPU_DISABLE`` (its AVX,
AVX2, FMA3 and AVX-512 paths). The capped worker checks each cap from inside (numpy's dispatch table,
``cv2.checkHardwareSupport``, the oneDNN variable) and the script fails when one is not in force, or when a capped
OpenVINO run of the accurate model is not slower than the uncapped one. onnxruntime has no such cap: its rows run at
the full instruction set and say so.

Each front end is timed as a user calls it, ``naoslam.FrontEnd(model, threads=1, engine=...)(frame, camera_pose)``,
on the frames of a rendered walk with the camera's pose (the horizon band and the ground-plane gate), and without
the pose. The two-stage front end's candidates per frame are counted. The Atom estimate multiplies the capped time
by 7 to 10: per clock Silvermont issues one 4-wide multiply every two cycles and one add per cycle, a current
desktop core two of each per cycle (LLVM's scheduling models for SLM and Znver4), about 4x; with the clocks 7-10x
per core.

A second table times the robot front ends on real Nao frames, where ``../shared`` holds them: ``real-poles`` and
``real-backgrounds`` (no camera pose recorded, so the whole frame is searched), at their own sizes and at 640x480,
each frame the best of three runs; the median, 95th percentile and worst frame, the finder's windows, the crops the
crop network looked at (first and second looks) and the share of frames that hit the window budget. These are the
frames a team's robot sees: cluttered, every one filling the finder's cap.

A third table is a real rate: a 30 fps camera for ``CAMERA_SECONDS``, one thread taking the newest frame whenever
it is free, front end and EKF SLAM update on it; frames that arrive while it works are dropped, as on the robot.
Usage: python benchmarks/bench_robot.py [FRAMES] [REPEATS] [--before OLD_ROBOT_MODEL.onnx]
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import time

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from detector import speed  # noqa: E402  (the repository on the path first)

#: Real Nao frames without a recorded pose (``../shared``, where present): the folders of each set.
SHARED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), os.pardir, "shared")
REAL_SETS = (("real-poles", "real-poles/test/images"), ("real-backgrounds", "real-backgrounds/images"))
REAL_REPEATS = 3
#: (label, model) of each front end, the shipped robot model first.
MODELS = [("robot, two-stage", "shipped-robot"), ("accurate INT8", "shipped-int8")]
ENGINES = ("openvino", "onnxruntime")
CAMERA_FPS = 30.0
CAMERA_SECONDS = 20.0


def measure(models: list[tuple[str, str]], count: int, repeats: int) -> dict:
    """Every front end and engine in this process: {key: ms, or a reason it did not run}."""
    import cv2
    from bench_engines import walk_frames

    import naoslam
    from naoslam.perception.colour_filter import ColourFilter

    cv2.setNumThreads(1)
    frames, poses = walk_frames(count)
    results: dict[str, float | str] = {}
    for label, model in models:
        for engine in ENGINES:
            key = f"{label}|{engine}"
            try:
                front_end = naoslam.FrontEnd(model, threads=1, engine=engine)
                front_end(frames[0], poses[0])
            except Exception as error:  # an operator with no primitive at this instruction set, a missing model
                results[f"{key}|pose"] = f"does not run: {str(error).splitlines()[0][:80]}"
                continue
            results[f"{key}|pose"] = speed.median_ms(lambda i: front_end(frames[i], poses[i]), range(count), repeats)
            results[f"{key}|no pose"] = speed.median_ms(lambda i: front_end(frames[i]), range(count), repeats)
            finder = getattr(front_end.detector, "finder", None)
            if finder is not None:
                views = [front_end.detector.ground_view(f.shape[:2], p) for f, p in zip(frames, poses)]
                results[f"{key}|candidates"] = float(np.mean([len(finder(f, v)) for f, v in zip(frames, views)]))
    results["colour filter|opencv|no pose"] = speed.median_ms(ColourFilter(), frames, repeats)
    return results


def real_frame_sets() -> dict[str, list]:
    """Every real set present, at its own sizes and at 640x480: {"set (size)": [BGR frames]}."""
    import cv2

    sets = {}
    for name, folder in REAL_SETS:
        paths = sorted(glob.glob(os.path.join(SHARED, folder, "*.jpg")) + glob.glob(os.path.join(SHARED, folder, "*.png")))
        frames = [frame for frame in (cv2.imread(path) for path in paths) if frame is not None]
        if frames:
            sets[f"{name} (own sizes)"] = frames
            sets[f"{name} (640x480)"] = [cv2.resize(f, (640, 480), interpolation=cv2.INTER_AREA) for f in frames]
    return sets


def measure_real(models: list[tuple[str, str]]) -> dict:
    """Each robot front end on every real set: per-frame ms (best of ``REAL_REPEATS``), windows, crops looked at and
    budget hits, summarised; {label: {set: figures}}."""
    import cv2

    from naoslam.perception.two_stage import CropDetector

    cv2.setNumThreads(1)
    sets = real_frame_sets()
    results: dict[str, dict] = {}
    for label, model in models:
        detector = CropDetector(model, threads=1, engine="openvino")
        for frames in sets.values():  # compile every batch shape and warm up before timing
            for frame in frames[:10]:
                detector(frame)
        results[label] = {}
        for name, frames in sets.items():
            times, windows, looked, hits = [], [], [], []
            for frame in frames:
                best = min(_seconds(detector, frame) for _ in range(REAL_REPEATS))
                times.append(1000 * best)
                windows.append(detector.cost.windows)
                looked.append(detector.cost.looked_at + detector.cost.second_looks)
                hits.append(detector.cost.hit_budget)
            results[label][name] = {"frames": len(frames), "median": float(np.median(times)),
                                    "p95": float(np.percentile(times, 95)), "worst": float(np.max(times)),
                                    "windows": float(np.mean(windows)), "looked": float(np.mean(looked)),
                                    "budget_hits": float(np.mean(hits))}
    return results


def _seconds(detector, frame) -> float:
    start = time.perf_counter()
    detector(frame)
    return time.perf_counter() - start


def camera_rate(model: str, engine: str) -> dict:
    """The robot's loop against a 30 fps camera: frames processed per second and dropped, with EKF SLAM updates."""
    import naoslam
    from detector.synth.walk import frame_steps, render_walk, walk_camera_poses
    from naoslam.motion import OdometryModel
    from naoslam.sim import SimConfig, simulate

    walk = simulate(SimConfig(seed=3, duration_s=CAMERA_SECONDS))
    frames, poses = render_walk(walk, seed=3, progress=False), walk_camera_poses(walk, 3)
    odometry = [walk.steps[i].odometry_pose for i in frame_steps(walk)]
    front_end = naoslam.FrontEnd(model, threads=1, engine=engine)
    front_end(frames[0], poses[0])  # compile and warm up before the camera starts
    slam = naoslam.EkfSlam(odometry[0], np.diag([0.01, 0.01, 0.01]) ** 2, OdometryModel(), naoslam.SlamConfig())
    processed, previous, start = 0, None, time.perf_counter()
    total = int(CAMERA_SECONDS * CAMERA_FPS)
    while (arrived := int((time.perf_counter() - start) * CAMERA_FPS)) < total:
        if arrived == previous:  # the newest frame is done: wait for the next one
            time.sleep(max(0.0, (arrived + 1) / CAMERA_FPS - (time.perf_counter() - start)))
            continue
        i = arrived * len(frames) // total  # the walk's frame the camera shows at this moment
        if previous is not None:
            slam.predict(OdometryModel.control(odometry[previous * len(frames) // total], odometry[i]))
        slam.update(front_end(frames[i], poses[i]))
        processed, previous = processed + 1, arrived
    return {"processed_fps": processed / CAMERA_SECONDS, "dropped": total - processed, "frames": total}


def run_worker(capped: bool, task: dict) -> dict:
    """``task`` in a fresh process (the caps must be set before the libraries load); a capped worker refuses to run
    when a cap is not in force."""
    try:
        return speed.run_worker([sys.executable, __file__, "--worker"], capped, task)
    except RuntimeError as failure:
        raise SystemExit(str(failure)) from None


def worker(task: dict) -> dict:
    if task["capped"] and (problems := speed.caps_in_force()):
        raise SystemExit("the Atom cap is not in force: " + "; ".join(problems))
    if "camera" in task:
        return camera_rate(*task["camera"])
    if "real" in task:
        return measure_real([tuple(m) for m in task["real"]])
    return measure([tuple(m) for m in task["models"]], task["frames"], task["repeats"])


def cell(value, atom: bool = False) -> str:
    if isinstance(value, str):
        return value
    if value is None:
        return "-"
    if atom:
        low, high = (value * factor for factor in speed.ATOM_FACTORS)
        return f"{low:.0f}-{high:.0f}"
    return f"{value:.2f}"


def speed_table(models: list[tuple[str, str]], count: int, repeats: int) -> tuple[dict, dict]:
    """The capped and the uncapped measurements (each in its own process)."""
    task = {"models": models, "frames": count, "repeats": repeats}
    return run_worker(True, task), run_worker(False, task)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frames", type=int, nargs="?", default=20)
    parser.add_argument("repeats", type=int, nargs="?", default=3)
    parser.add_argument("--before", help="the robot model this one replaces (an ONNX file), timed beside it")
    args = parser.parse_args()
    models = MODELS + ([("the one before", args.before)] if args.before else [])
    capped, uncapped = speed_table(models, args.frames, args.repeats)
    print(f"{args.frames} walk frames (640x480), {args.repeats} passes, one thread; ms per frame. Capped: OpenVINO "
          "(oneDNN SSE4.1), numpy (no AVX2/AVX-512 dispatch) and OpenCV (no AVX/AVX2/FMA3/AVX-512), checked in the "
          "worker; onnxruntime cannot be capped.")
    print("| front end | engine | with pose, capped | without pose, capped | with pose, full ISA | "
          "Atom E3845 estimate, with pose (x7-10) | candidates / frame |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for label, _ in models + [("colour filter", "")]:
        for engine in ("opencv",) if label == "colour filter" else ENGINES:
            key = f"{label}|{engine}"
            capped_pose = capped.get(f"{key}|pose") if engine != "onnxruntime" else "no cap"
            capped_plain = capped.get(f"{key}|no pose") if engine != "onnxruntime" else "no cap"
            atom = cell(capped_pose, atom=True) if engine == "openvino" else "-"
            print(f"| {label} | {engine} | {cell(capped_pose)} | {cell(capped_plain)} | "
                  f"{cell(uncapped.get(f'{key}|pose'))} | {atom} | {cell(uncapped.get(f'{key}|candidates'))} |")
    robots = [(label, model) for label, model in models if label != "accurate INT8"]
    real = run_worker(True, {"real": robots})
    if any(real.values()):
        print(f"\nReal Nao frames without a pose (../shared), capped as above, one thread, each frame the best of "
              f"{REAL_REPEATS} runs; ms per frame")
        print("| front end | frames | median | 95th percentile | worst | windows / frame | crops looked at / frame | "
              "frames at the window budget |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        for label, sets in real.items():
            for name, row in sets.items():
                print(f"| {label} | {name}, {row['frames']} | {row['median']:.2f} | {row['p95']:.2f} | "
                      f"{row['worst']:.2f} | {row['windows']:.1f} | {row['looked']:.1f} | "
                      f"{100 * row['budget_hits']:.0f} % |")
    print(f"\nA {CAMERA_FPS:.0f} fps camera for {CAMERA_SECONDS:.0f} s, one thread, front end and EKF SLAM on the "
          "newest frame")
    print("| front end | engine | frames processed per second | dropped |")
    print("| --- | --- | --- | --- |")
    for label, model in models:
        for engine, capped_run in (("openvino", True), ("onnxruntime", False)):
            rate = run_worker(capped_run, {"camera": [model, engine]})
            print(f"| {label} | {engine}{' capped' if capped_run else ''} | {rate['processed_fps']:.1f} | "
                  f"{rate['dropped']} of {rate['frames']} |", flush=True)
    # The worker checks each cap from inside; this checks that the cap shows where the network's arithmetic dominates
    # (the accurate model). A robot front end of a few ms drifts by more than the cap costs it on this machine.
    slower = [key for key, value in capped.items() if key.startswith("accurate") and "openvino|pose" in key
              and isinstance(value, float) and isinstance(uncapped.get(key), float) and value <= uncapped[key]]
    if slower:
        raise SystemExit(f"the SSE4.1 cap was not in force: capped runs not slower for {slower}")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    if sys.argv[1:2] == ["--worker"]:
        print(json.dumps(worker(json.loads(sys.argv[2]))))
    else:
        main()
