"""How long a whole front end takes per frame as the robot runs it: ``naoslam.FrontEnd(model, threads=1,
engine=...)`` on frames with their camera poses, timed in a fresh process, capped at the Nao's instruction set or not.

The Atom E3845 has SSE4.2 and no AVX. Three libraries dispatch on the instruction set, and each is capped before it
loads: OpenVINO's CPU plugin (oneDNN) by ``ONEDNN_MAX_CPU_ISA=SSE41``, numpy by ``NPY_DISABLE_CPU_FEATURES`` (its
AVX2 and AVX-512 dispatch targets), OpenCV by ``OPENCV_CPU_DISABLE`` (its AVX, AVX2, FMA3 and AVX-512 paths). A
capped worker checks each cap from inside and refuses to time when one is not in force. onnxruntime has no such cap.

The Atom estimate multiplies the capped time by 7 to 10: per clock Silvermont issues one 4-wide multiply every two
cycles and one add per cycle, a current desktop core two of each per cycle (LLVM's scheduling models for SLM and
Znver4), about 4x; with the clocks 7-10x per core.

Run as ``python -m detector.speed TASK_JSON`` it is that worker: it prints its measurements as one JSON line.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterable

import numpy as np

#: The Atom's instruction set, for each library that dispatches on it.
CAPS = {"ONEDNN_MAX_CPU_ISA": "SSE41", "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "OPENCV_CPU_DISABLE": "AVX,AVX2,FP16,FMA3,AVX512F,AVX512-SKX"}
#: OpenCV's ids of the features the cap must switch off (``cv::CpuFeatures``): AVX, AVX2, FMA3, AVX-512F, AVX512-SKX.
OPENCV_ABOVE_ATOM = {"AVX": 10, "AVX2": 11, "FMA3": 12, "AVX_512F": 13, "AVX512_SKX": 256}
#: The Atom estimate's range: capped time on this machine times these (see the module's docstring).
ATOM_FACTORS = (7.0, 10.0)


def caps_in_force() -> list[str]:
    """What of the Atom cap is not in force in this process (empty when all of it is)."""
    import cv2
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    problems = [f"numpy dispatches {target}" for target in __cpu_dispatch__ if __cpu_features__.get(target)]
    problems += [f"OpenCV uses {name}" for name, feature in OPENCV_ABOVE_ATOM.items()
                 if cv2.checkHardwareSupport(feature)]
    if os.environ.get("ONEDNN_MAX_CPU_ISA") != CAPS["ONEDNN_MAX_CPU_ISA"]:
        problems.append("oneDNN (OpenVINO) is not capped: ONEDNN_MAX_CPU_ISA is not SSE41")
    return problems


def median_ms(run: Callable[[object], object], items: Iterable, repeats: int) -> float:
    """Median ms of ``run(item)`` over ``repeats`` passes over ``items`` (one warm-up pass first)."""
    items = list(items)
    for item in items:
        run(item)
    times = []
    for _ in range(repeats):
        for item in items:
            start = time.perf_counter()
            run(item)
            times.append(time.perf_counter() - start)
    return 1000 * float(np.median(times))


def worker_environment(capped: bool) -> dict[str, str]:
    """One thread everywhere; the Atom cap on every library, or none of it."""
    env = {key: value for key, value in os.environ.items() if key not in CAPS}
    env.update({"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", **(CAPS if capped else {})})
    return env


def run_worker(command: list[str], capped: bool, task: dict) -> dict:
    """``command`` (a Python worker that takes the task as its last argument and prints one JSON line) in a fresh
    process, capped or not; RuntimeError with its last words when it fails."""
    out = subprocess.run([*command, json.dumps({**task, "capped": capped})], env=worker_environment(capped),
                         capture_output=True, text=True)
    if out.returncode:
        raise RuntimeError(f"the timing worker failed: {out.stderr.strip().splitlines()[-1:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def time_front_ends(models: list[tuple[str, str]], frames: list[str], poses: list[tuple[float, float, float]],
                    repeats: int) -> dict[str, dict[str, float | str]]:
    """Each front end's median ms per frame on ``frames`` (image files) with their camera ``poses`` (height, pitch,
    roll), one thread, OpenVINO when installed: ``{"capped": {label: ms or why not}, "uncapped": {...}}``."""
    task = {"models": models, "frames": frames, "poses": poses, "repeats": repeats}
    command = [sys.executable, "-m", "detector.speed"]
    return {"capped" if capped else "uncapped": run_worker(command, capped, task) for capped in (True, False)}


def engine() -> str:
    """OpenVINO where it is installed (the engine the Atom figures are for), else onnxruntime."""
    try:
        import openvino  # noqa: F401  (only asked whether it imports)
    except ImportError:
        return "onnxruntime"
    return "openvino"


def _measure(task: dict) -> dict[str, float | str]:
    """The worker: every front end on the task's frames, in this process."""
    import cv2

    import naoslam
    from naoslam.camera import CameraPose

    if task["capped"] and (problems := caps_in_force()):
        return {label: "not timed: the Atom cap is not in force (" + "; ".join(problems) + ")"
                for label, _ in task["models"]}
    cv2.setNumThreads(1)
    frames = [cv2.imread(path) for path in task["frames"]]
    poses = [CameraPose(z=z, pitch=pitch, roll=roll) for z, pitch, roll in task["poses"]]
    chosen = engine()
    if task["capped"] and chosen != "openvino":
        return {label: "not timed: OpenVINO is not installed, and onnxruntime cannot be capped"
                for label, _ in task["models"]}
    results: dict[str, float | str] = {}
    for label, model in task["models"]:
        try:
            front_end = naoslam.FrontEnd(model, threads=1, engine=chosen)
        except Exception as error:  # an operator with no primitive at this instruction set, a missing model
            results[label] = f"does not run: {str(error).splitlines()[0][:80]}"
            continue
        results[label] = median_ms(lambda i: front_end(frames[i], poses[i]), range(len(frames)), task["repeats"])
    return results


if __name__ == "__main__":
    print(json.dumps(_measure(json.loads(sys.argv[1]))))
