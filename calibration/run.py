"""``poles calibrate``: measure, fit, report, plot, write calibration.json, optionally embed it in a model."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from rich.table import Table

from calibration.fit import MIN_NOISE_SIGHTINGS, WALK_RELATIVE_STD, calibrate
from calibration.report import CalibrationReport
from calibration.samples import MEASURE_CONF, SizeSample, as_arrays, measure_samples, measures_law, open_ranged
from detector.outputs import check_output_file
from detector.formats import write_record
from detector.console import make_console
from detector.figures import log_log, plt, save_figure
from detector.model_files import add_metadata, read_info
from detector.records import JsonRecord
from naoslam.perception.loading import load_detector
from naoslam.measurement import RangeCalibration

@dataclass(frozen=True)
class CalibrationResult(JsonRecord):
    """A fitted calibration, its report and its plot (None when none was asked for)."""

    calibration: RangeCalibration
    report: CalibrationReport
    plot: Path | None = None


#: The 2024 thesis's laws at 640x480, drawn for comparison.
THESIS_WIDTH_LAW = (70.057, -1.109)
THESIS_HEIGHT_LAW = (209.16, -0.965)


def run_calibration(data: Path, out: Path, model: Path | None = None, truth_csv: Path | None = None,
                    plot: Path | None = None, embed: Sequence[Path] = (), force: bool = False,
                    noise_data: Sequence[Path] = (), input_width: int | None = None) -> CalibrationResult:
    """Fit from ``data`` and write ``out`` (calibration + report); returns what was written. ``noise_data``: frames
    of a walk with true ranges (e.g. ``poles synth --walk``), measured the same way, set the noise the filter is
    told. ``input_width``: the ``model``'s input width on the robot (None: its own). ``embed``: ONNX models to store
    the calibration in."""
    if plot is not None and Path(plot).suffix.lower() != ".png":
        raise ValueError(f"--plot {plot}: the fit plot is written as PNG - name it *.png; nothing was written")
    if input_width is not None and model is None:
        raise ValueError("--imgsz is a model's input width: give --model (label masks have no input width)")
    ranged = open_ranged(data, truth_csv)
    walks = [open_ranged(folder) for folder in noise_data]  # every input checked before any is measured
    read = [ranged.dataset, *(walk.dataset for walk in walks)]
    inputs = tuple(Path(path) for path in (data, truth_csv, model, *embed, *noise_data) if path is not None) + \
        tuple(folder for dataset in read for folder in dataset.input_folders())
    for output in (out, plot) if plot else (out,):
        check_output_file(output, force, inputs)
    if embed:
        for target in embed:
            read_info(target)  # refuse a model that cannot take the calibration before anything is written
    detector = load_detector(model, conf=MEASURE_CONF, input_width=input_width) if model else None
    samples = measure_samples(ranged, detector)
    ranges = sorted({round(sample.range_m, 3) for sample in samples})
    if len(ranges) < 2:
        source = truth_csv or Path(data) / "annotations.json"
        raise ValueError(f"{source}: every pole measured stands at {ranges[0]:g} m - a range law needs poles at two "
                         "or more distances: add shots from other distances; nothing was written")
    walk = [s for w in walks for s in measure_samples(w, detector)] if walks else None
    calibration, report = calibrate(samples, walk_samples=walk)
    calibration = replace(calibration, input_width=detector.calibration_width if detector else None)
    source = ((f"boxes of {model} at the frames' own pixels" if calibration.input_width is None else
               f"masks of {model} at {calibration.input_width} px input") if model else "label masks")
    noise_source = (", ".join(str(folder) for folder in noise_data) if noise_data
                    else "rendered walks with the shipped model at 640 px input (the default; --noise-data measures "
                         "your own)")
    result = CalibrationResult(calibration, report.with_sources(source, noise_source), plot)
    for target in embed:
        embed_calibration(target, calibration)
    write_record(out, "calibration", {"calibration": calibration.to_dict(), "report": result.report.to_json()})
    if plot:
        plot_fit(samples, calibration, plot, walk)
    return result


def embed_calibration(model: Path, calibration: RangeCalibration) -> Path:
    """Store the calibration in the ONNX model's naoslam metadata (the weights are untouched)."""
    return add_metadata(model, calibration=calibration.to_dict())


def plot_fit(samples: list[SizeSample], calibration: RangeCalibration, png: Path,
             walk_samples: list[SizeSample] | None = None) -> Path:
    """Range against width and height (log-log) with the fitted laws and the thesis's, behind them the walk's
    sightings (``--noise-data``) whose spread the filter is told."""
    hfov = calibration.hfov_deg if calibration.off_axis_corrected else None
    columns = as_arrays(samples, calibration.reference_width_px, hfov)
    walk = as_arrays(walk_samples, calibration.reference_width_px, hfov) if walk_samples else None
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True)
    for ax, key, law, thesis in ((axes[0], "width", calibration.width_law, THESIS_WIDTH_LAW),
                                 (axes[1], "height", calibration.height_law, THESIS_HEIGHT_LAW)):
        px = columns[key]
        if walk is not None:
            shown = measures_law(walk, key)
            ax.scatter(walk[key][shown], walk["range"][shown], s=4, color="0.75", zorder=0,
                       label=f"walk sightings (told {100 * law.relative_std:.1f} %)")
        ax.scatter(px[~columns["partial"]], columns["range"][~columns["partial"]], s=12, label="whole pole")
        if columns["partial"].any():
            ax.scatter(px[columns["partial"]], columns["range"][columns["partial"]], s=12, marker="x",
                       label="partly outside the image")
        grid = np.geomspace(max(px.min() * 0.8, 1), px.max() * 1.25, 100)
        ax.plot(grid, law(grid), label=f"fit {law.a:.4g} px^{law.b:.3f}")
        if calibration.reference_width_px == 640:
            ax.plot(grid, thesis[0] * grid ** thesis[1], linestyle="--", label=f"thesis {thesis[0]} px^{thesis[1]}")
        log_log(ax)
        on_axis = ", on the optical axis" if calibration.off_axis_corrected else ""
        ax.set_xlabel(f"rotated-box {key} (px)\nat {calibration.reference_width_px} px image width{on_axis}")
        ax.set_ylabel("true range (m)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle("range calibration")
    return save_figure(fig, png)


def print_calibration(result: CalibrationResult) -> None:
    """The laws and the per-distance errors as tables."""
    report, calibration = result.report, result.calibration
    laws = Table(title=f"range laws from {report.samples} poles ({report.source}), "
                       f"pixels at {report.reference_width_px} px width")
    for column in ("law", "a", "b", "R^2", "relative std", "filter is told", "thesis-style fit (per-range means)"):
        laws.add_column(column)
    told = {"width": calibration.width_law, "height": calibration.height_law, "colour": calibration.colour_law}
    for key, fit in report.laws().items():
        mean_fit = fit.per_distance_mean_fit
        laws.add_row(key if key != "colour" else "colour (px per cm)", f"{fit.a:.4g}", f"{fit.b:.4f}",
                     f"{fit.r2:.4f}", f"{100 * fit.relative_std:.1f} %", f"{100 * told[key].relative_std:.1f} %",
                     f"{mean_fit.a:.4g} * x^{mean_fit.b:.4f}" if mean_fit else "-")
    errors = Table(title="mean relative range error by true range (foot: poles with a camera pose and the foot "
                         "in view)")
    for column in ("range (m)", "poles", "width", "height", "thesis rule", "fused", "foot (poles)", "fused+foot"):
        errors.add_column(column, justify="right")
    cut = (report.errors_cut_by_border,) if report.errors_cut_by_border else ()
    for row in report.errors_by_range + cut:
        errors.add_row(row.label, str(row.samples),
                       *(f"{v:.1f} %" for v in (row.width, row.height, row.rule, row.fused)),
                       f"{row.foot:.1f} % ({row.foot_samples})" if row.foot is not None else "-",
                       f"{row.fused_foot:.1f} %" if row.fused_foot is not None else "-")
    console = make_console()
    console.print(laws)
    walk = {key: law.walk for key, law in report.laws().items() if law.walk is not None}
    floors = (", ".join(f"{key} {100 * w.relative_std:.1f} % (median error {100 * w.median_log_error:+.1f} %, "
                        f"{w.sightings} sightings)" for key, w in walk.items()) if walk
              else ", ".join(f"{key} {100 * std:.1f} %" for key, std in WALK_RELATIVE_STD.items()))
    if report.colour is not None and report.colour.walk_too_few is not None:
        floors += (f", colour {100 * WALK_RELATIVE_STD['colour']:.1f} % (the default: the colour filter found "
                   f"{report.colour.walk_too_few} poles in the walk, {MIN_NOISE_SIGHTINGS} needed)")
    console.print(f"the filter is told the larger of each law's residual and a walking robot's noise: {floors}, "
                  f"measured on {report.noise_source}")
    console.print(errors)
    bearing = report.bearing_error_deg
    console.print(f"upright width/height ratio {report.upright_ratio:.3f}"
                  + (f"; bearing error {bearing.mean:+.2f} +- {bearing.std:.2f} deg" if bearing else ""))
