"""Where an ONNX pole model spends its time on the Nao's instruction set: OpenVINO's per-layer counters.

The model runs under OpenVINO's CPU plugin, one thread, FP32, with oneDNN capped at SSE4.1 (the Atom's level) unless
``--uncapped``. The table lists the slowest layers with the kernel each ran on. A layer on ``jit_gemm`` or ``ref``
instead of a ``jit_sse42`` kernel has fallen off oneDNN's fast path; that is how the head rewrites in
``export/atom_graph.py`` were found. The totals per kernel come first.
Usage: python benchmarks/profile_layers.py MODEL.onnx [--hw 256 320] [--top 25] [--uncapped]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections import defaultdict

import numpy as np

from detector.speed import CAPS
from naoslam.perception.engines import openvino_config


def profile(model: str, input_hw: tuple[int, int], top: int, repeats: int = 30) -> None:
    """Print the median bare-pass time, the time per (layer type, kernel) and the ``top`` slowest layers."""
    import openvino as ov

    core = ov.Core()
    network = core.read_model(model)
    network.reshape({network.inputs[0]: [1, 3, *input_hw]})
    compiled = core.compile_model(network, "CPU", openvino_config(1, PERF_COUNT=True))
    request = compiled.create_infer_request()
    blob = np.random.default_rng(0).random((1, 3, *input_hw), dtype=np.float32)
    for _ in range(5):
        request.infer({0: blob})
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        request.infer({0: blob})
        times.append(time.perf_counter() - start)
    layers = sorted(((p.real_time.total_seconds() * 1e3, p.node_type, p.exec_type, p.node_name)
                     for p in request.get_profiling_info()), reverse=True)
    cap = os.environ.get("ONEDNN_MAX_CPU_ISA", "none (full instruction set)")
    print(f"{model} at {input_hw[1]}x{input_hw[0]}, one thread, cap {cap}: median {1000 * np.median(times):.2f} ms "
          f"per pass, layers sum to {sum(layer[0] for layer in layers):.2f} ms (last pass)")
    per_kernel: dict[tuple[str, str], float] = defaultdict(float)
    for ms, node_type, kernel, _ in layers:
        per_kernel[(node_type, kernel)] += ms
    print("| layer type | kernel | ms |\n| --- | --- | --- |")
    for (node_type, kernel), ms in sorted(per_kernel.items(), key=lambda item: -item[1]):
        if ms >= 0.01:
            print(f"| {node_type} | {kernel} | {ms:.2f} |")
    print("\n| ms | layer type | kernel | layer |\n| --- | --- | --- | --- |")
    for ms, node_type, kernel, name in layers[:top]:
        print(f"| {ms:.3f} | {node_type} | {kernel} | {name} |")


def main(argv: list[str]) -> None:
    parser = argparse.ArgumentParser(prog="profile_layers.py", description=__doc__.splitlines()[0])
    parser.add_argument("model", help="an ONNX file, e.g. naoslam/models/poles-robot.onnx")
    parser.add_argument("--hw", type=int, nargs=2, default=(256, 320), metavar=("HEIGHT", "WIDTH"),
                        help="network input (default 256 320, the robot model's; 480 640 for the accurate one)")
    parser.add_argument("--top", type=int, default=25, help="slowest layers listed (default 25)")
    parser.add_argument("--uncapped", action="store_true", help="this machine's full instruction set")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if not os.path.isfile(args.model):
        sys.exit(f"{args.model}: no such model file - pass an exported ONNX model")
    if args.worker:
        profile(args.model, tuple(args.hw), args.top)
        return
    env = {**os.environ, "OMP_NUM_THREADS": "1", **({} if args.uncapped else CAPS)}
    if args.uncapped:
        env.pop("ONEDNN_MAX_CPU_ISA", None)
    # The cap must be in the environment before OpenVINO loads: a fresh process.
    sys.exit(subprocess.run([sys.executable, __file__, *argv, "--worker"], env=env).returncode)


if __name__ == "__main__":
    main(sys.argv[1:])
