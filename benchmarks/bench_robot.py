"""The robot budget: each pole model's whole front end per 640x480 frame on one thread, at the Nao's instruction set.

The Nao v6's Atom E3845 has SSE4.2 and no AVX. OpenVINO's CPU plugin (oneDNN) honours ``ONEDNN_MAX_CPU_ISA=SSE41``,
so a second process runs every model with that cap; an operator without an SSE4.1 primitive refuses to compile there,
and the table says so. onnxruntime has no such cap: its rows run at this machine's full instruction set. OpenCV and
numpy (letterbox, decoding, masks, rotated boxes) are not capped either. The front end is ``LandmarkDetector``'s
call (letterbox, forward pass, NMS, masks, rotated boxes, ground gate) plus range and bearing from the model's
calibration, the frame's ground view built once for both, as ``naoslam.FrontEnd`` does; "bare" is the forward pass alone on a prepared tensor. Frames: a rendered walk, so the horizon band is the one the
robot would crop. Ratios are to the shipped accurate model's INT8 copy under OpenVINO in the same process.
The script fails when the capped run is not slower than the uncapped one (the cap was not in force).

A second table is a real rate: a camera delivering 640x480 frames at 30 fps for ``CAMERA_SECONDS`` (frames rendered
along a walk, replayed on the clock), one thread taking the newest frame whenever it is free, running the front end
and the EKF SLAM update (and the odometry prediction) on it; frames that arrive while it works are dropped, as on the
robot. It reports frames processed per second and dropped.
Usage: python benchmarks/bench_robot.py [FRAMES] [REPEATS]
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np

os.environ.setdefault("YOLO_OFFLINE", "true")

#: The instruction-set cap oneDNN honours: SSE4.1, the Atom's level (it also has SSE4.2, which oneDNN does not use).
CAP = {"ONEDNN_MAX_CPU_ISA": "SSE41"}
#: (label, shipped name) of each model, the reference first.
MODELS = (("accurate INT8", "shipped-int8"), ("accurate FP32", "shipped"), ("robot", "shipped-robot"))
ENGINES = ("openvino", "onnxruntime")
#: The Nao's top camera rate, and how long the camera-rate loop runs.
CAMERA_FPS = 30.0
CAMERA_SECONDS = 20.0


def median_ms(run, items, repeats: int) -> float:
    """Median ms of ``run(item)`` over ``repeats`` passes over ``items`` (one warm-up pass first)."""
    for item in items:
        run(item)
    times = []
    for _ in range(repeats):
        for item in items:
            start = time.perf_counter()
            run(item)
            times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def measure(count: int, repeats: int) -> dict:
    """Every model, engine and input in this process: {key: ms or a reason it did not run}."""
    from bench_engines import walk_frames

    from naoslam.colour_filter import ColourFilter
    from naoslam.detector import LandmarkDetector
    from naoslam.measurement import MeasurementModel

    frames, poses = walk_frames(count)
    results: dict[str, float | str] = {}
    for label, name in MODELS:
        for engine in ENGINES:
            try:
                detector = LandmarkDetector(name, threads=1, engine=engine)
                detector(frames[0])
            except Exception as error:  # an operator with no primitive at this instruction set, a missing model
                results[f"{label}|{engine}|whole"] = f"does not run: {str(error).splitlines()[0][:80]}"
                continue
            calibration = detector.usable_calibration
            measurement = MeasurementModel(calibration, min_confidence=0.0) if calibration else None
            blobs = [detector.prepare(f)[0] for f in frames]
            results[f"{label}|{engine}|bare"] = median_ms(detector.forward, blobs, repeats)
            for crop in (False, True):
                def front_end(i: int) -> None:  # as naoslam.FrontEnd: one ground view per frame, gate and ranges
                    view = detector.ground_view(frames[i].shape[:2], poses[i])
                    found = detector(frames[i], poses[i], crop=crop, view=view)
                    if measurement is not None:
                        measurement.measure(found, frames[i].shape[1], view=view)
                results[f"{label}|{engine}|{'band' if crop else 'whole'}"] = median_ms(front_end, range(count), repeats)
    colour_filter = ColourFilter()
    results["colour filter|opencv|whole"] = median_ms(colour_filter, frames, repeats)
    return results


def camera_rate(model: str, engine: str) -> dict:
    """The robot's loop against a 30 fps camera: frames processed per second and dropped, with EKF SLAM updates."""
    import naoslam
    from detector.synth.walk import frame_steps, render_walk, walk_camera_poses
    from naoslam.motion import OdometryModel
    from naoslam.sim import SimConfig, simulate

    walk = simulate(SimConfig(seed=3, duration_s=CAMERA_SECONDS))
    frames, poses = render_walk(walk, seed=3, progress=False), walk_camera_poses(walk, 3)
    odometry = [walk.steps[i].odometry_pose for i in frame_steps(walk)]
    front_end = naoslam.FrontEnd(naoslam.LandmarkDetector(model, threads=1, engine=engine))
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


def run_worker(capped: bool, count: int, repeats: int, task: list[str] | None = None) -> dict:
    """``measure`` (or ``task``) in a fresh process (the cap must be set before OpenVINO loads), one thread
    everywhere."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", **(CAP if capped else {})}
    if not capped:
        env.pop("ONEDNN_MAX_CPU_ISA", None)
    out = subprocess.run([sys.executable, __file__, "--worker", str(count), str(repeats), *(task or [])], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def cell(value, reference) -> str:
    if isinstance(value, str):
        return value
    ratio = f" ({value / reference:.2f}x)" if isinstance(reference, float) else ""
    return f"{value:.1f}{ratio}"


def main(count: int, repeats: int) -> None:
    capped, uncapped = run_worker(True, count, repeats), run_worker(False, count, repeats)
    reference = "accurate INT8|openvino|whole"
    print(f"{count} walk frames (640x480), {repeats} passes, one thread; ms per frame (ratio to the accurate INT8 "
          "model, OpenVINO, whole frame, same column)")
    print("| model | engine | input | capped at SSE4.1 | this machine's full ISA |")
    print("| --- | --- | --- | --- | --- |")
    for key in uncapped:
        label, engine, part = key.split("|")
        capped_cell = cell(capped.get(key, "-"), capped.get(reference)) if engine != "onnxruntime" else "no cap"
        print(f"| {label} | {engine} | {part} | {capped_cell} | {cell(uncapped[key], uncapped.get(reference))} |")
    for label, _ in MODELS:
        for engine, results in (("openvino", capped), ("onnxruntime", uncapped)):
            bare, whole = results.get(f"{label}|{engine}|bare"), results.get(f"{label}|{engine}|whole")
            if isinstance(bare, float) and isinstance(whole, float):
                print(f"front end / bare forward pass, {label}, {engine}"
                      f"{' capped' if engine == 'openvino' else ''}: {whole / bare:.2f}x")
    print(f"\nA {CAMERA_FPS:.0f} fps camera for {CAMERA_SECONDS:.0f} s, one thread, front end and EKF SLAM on the "
          "newest frame")
    print("| model | engine | frames processed per second | dropped |")
    print("| --- | --- | --- | --- |")
    for label, name in MODELS[2:] + MODELS[:1]:
        for engine, capped_run in (("openvino", True), ("onnxruntime", False)):
            rate = run_worker(capped_run, 0, 0, ["--camera", name, engine])
            print(f"| {label} | {engine}{' capped at SSE4.1' if capped_run else ''} | {rate['processed_fps']:.1f} | "
                  f"{rate['dropped']} of {rate['frames']} |", flush=True)
    slower = [key for key, value in capped.items() if "openvino" in key and isinstance(value, float)
              and isinstance(uncapped.get(key), float) and value <= uncapped[key]]
    if slower or not isinstance(capped.get(reference), float):
        raise SystemExit(f"the SSE4.1 cap was not in force: capped runs not slower for {slower or [reference]}")


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    if sys.argv[1:2] == ["--worker"] and sys.argv[4:5] == ["--camera"]:
        print(json.dumps(camera_rate(sys.argv[5], sys.argv[6])))
    elif sys.argv[1:2] == ["--worker"]:
        print(json.dumps(measure(int(sys.argv[2]), int(sys.argv[3]))))
    else:
        main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, int(sys.argv[2]) if len(sys.argv) > 2 else 3)
