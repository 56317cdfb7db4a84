"""``poles --version``: what a bug report needs."""
from __future__ import annotations

import argparse


def version_text() -> str:
    """What ``poles --version`` prints, for a bug report: this package, the shipped model it runs by default
    (file hash, threshold) and the versions of the libraries that train and run it."""
    import hashlib
    from importlib.metadata import PackageNotFoundError, version

    from naoslam.shipped import shipped_path

    def installed(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "not installed"

    model = shipped_path()
    if model.is_file():
        from naoslam.perception.yolo import LandmarkDetector

        digest = hashlib.sha256(model.read_bytes()).hexdigest()[:12]
        shipped = f"{model.name} (sha256 {digest}, threshold {LandmarkDetector(model).stored_conf})"
    else:
        shipped = "missing from this installation"
    libraries = ", ".join(f"{name} {installed(name)}" for name in
                          ("onnxruntime", "opencv-python-headless", "ultralytics-opencv-headless", "torch"))
    return f"poles {installed('nao-poles')}\nshipped model: {shipped}\n{libraries}"


class PrintVersion(argparse.Action):
    """``--version``, worked out only when asked for (it opens the shipped model)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version, the shipped model and the libraries")

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        print(version_text())
        parser.exit()
