"""Every JSON file poles writes for people's scripts carries its format number (``detector.formats``), and the number
moves whenever the file's fields change: each kind's fields are fingerprinted (a record's schema, field names and
types, without its docs; for the SLAM metrics, which naoslam writes as a plain dict, the keys a run writes) and
compared with ``tests/data/formats.json``. A change of fields with the same number fails here: move the kind's
number in ``FORMATS``, list what changed in docs/commands.md, and write the new fingerprints with
``python -m tests.test_formats``."""
from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import fields
from pathlib import Path

import pytest
from pydantic import TypeAdapter

from detector.formats import FORMATS, FormatMismatch, read_record, release, stamped, write_record

SNAPSHOT = Path(__file__).parent / "data" / "formats.json"


def _schema_free_of_prose(schema):
    """A JSON schema without titles and descriptions: a docstring's wording is not a field."""
    if isinstance(schema, dict):
        return {key: _schema_free_of_prose(value) for key, value in schema.items()
                if key not in ("title", "description")}
    if isinstance(schema, list):
        return [_schema_free_of_prose(value) for value in schema]
    return schema


def _key_paths(data, prefix: str = "") -> list[str]:
    """Every key of nested dicts as a dotted path (lists are not descended into)."""
    if not isinstance(data, dict):
        return []
    return sorted(path for key, value in data.items()
                  for path in [f"{prefix}{key}", *_key_paths(value, f"{prefix}{key}.")])


def _records() -> dict[str, object]:
    """Each kind's fields: a record type (its schema), or the key paths such a file holds."""
    from augment.run import AugmentSummary
    from calibration.report import CalibrationReport
    from detector.demo.results import DemoSlam, DemoSpeed, EvaluatedFrontEnd
    from detector.evaluation.results import Evaluation
    from detector.finetune.judge import JudgeRow
    from detector.finetune.results import FinetuneResult
    from detector.picking import PickResult
    from detector.robot_training import RobotTraining
    from detector.slam.comparison import BackendRow
    from detector.stages import StageRecord
    from detector.synth.generate import ANNOTATION_FIELDS
    from detector.synth.team_paint import TeamPaint
    from export.run import ExportReport
    from naoslam.ekf_slam import SlamConfig
    from naoslam.runner import run_slam
    from naoslam.shipped import shipped_path
    from naoslam.perception.yolo import LandmarkDetector
    from naoslam.sim import SimConfig
    from detector.slam.sequences import sim_sequence

    slam_metrics = {"sequence": "sim", **run_slam(sim_sequence(SimConfig(duration_s=4.0)), SlamConfig()).metrics()}
    calibration = LandmarkDetector(shipped_path()).calibration.to_dict()
    return {
        "evaluation": Evaluation, "finetune": FinetuneResult, "slam": _key_paths(slam_metrics),
        "slam map": ["landmarks"], "slam comparison": BackendRow,
        "calibration": [_key_paths({"calibration": calibration}), CalibrationReport],
        "export report": ExportReport, "stages": [field.name for field in fields(StageRecord) if field.name != "ran"],
        "robot training": RobotTraining, "augment": AugmentSummary, "paint": TeamPaint,
        "demo evaluation": EvaluatedFrontEnd, "demo slam": DemoSlam, "demo speed": DemoSpeed, "judgement": JudgeRow,
        "pick": PickResult,
        "annotations": ["classes", "generator", "fields", "images", *sorted(ANNOTATION_FIELDS)],
    }


def _fingerprint(spec) -> str:
    if isinstance(spec, list):
        parts = [_fingerprint(part) if isinstance(part, type) else part for part in spec]
        return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()[:16]
    schema = _schema_free_of_prose(TypeAdapter(spec).json_schema(mode="serialization"))
    return hashlib.sha256(json.dumps(schema, sort_keys=True).encode()).hexdigest()[:16]


@pytest.fixture(scope="module")
def fingerprints() -> dict[str, str]:
    return {kind: _fingerprint(spec) for kind, spec in _records().items()}


def test_every_kind_of_file_has_its_fields_fingerprinted(fingerprints):
    assert set(fingerprints) == set(FORMATS)
    assert set(json.loads(SNAPSHOT.read_text())) == set(FORMATS)


@pytest.mark.parametrize("kind", sorted(FORMATS))
def test_a_kind_s_fields_change_only_with_its_format_number(kind, fingerprints):
    number, fingerprint = json.loads(SNAPSHOT.read_text())[kind]
    assert FORMATS[kind] >= number, f"{kind}: its format number went back from {number} to {FORMATS[kind]}"
    if FORMATS[kind] == number:
        assert fingerprints[kind] == fingerprint, (
            f"the fields of {kind} files changed but its format is still {number}: move FORMATS[{kind!r}], list the "
            "change in docs/commands.md and run `python -m tests.test_formats`")


def test_a_file_carries_its_format_and_reads_back_without_the_stamp(tmp_path):
    path = write_record(tmp_path / "metrics.json", "evaluation", {"model": "shipped"})
    data = json.loads(path.read_text())
    assert (data["format"], data["kind"], data["written_by"]) == (FORMATS["evaluation"], "evaluation", release())
    assert read_record(path, "evaluation") == {"model": "shipped"}
    rows = write_record(tmp_path / "comparison.json", "slam comparison", [{"backend": "ekf"}])
    assert read_record(rows, "slam comparison") == {"rows": [{"backend": "ekf"}]}


def test_a_file_of_another_number_or_kind_is_refused_saying_who_wrote_it_and_what_to_do(tmp_path):
    flat = tmp_path / "old-metrics.json"  # written before numbers: an evaluation's counts at the top, format 1
    flat.write_text(json.dumps({"model": "shipped", "tp": 3, "fp": 0}))
    with pytest.raises(FormatMismatch, match="evaluation format 1, written by a poles release from before format "
                                             "numbers.*run the command that wrote it again"):
        read_record(flat, "evaluation")
    newer = tmp_path / "newer.json"
    newer.write_text(json.dumps({**stamped("calibration", {}), "format": 99, "written_by": "poles 9.0"}))
    with pytest.raises(FormatMismatch, match="calibration format 99, written by poles 9.0.*update poles"):
        read_record(newer, "calibration")
    with pytest.raises(FormatMismatch, match="a calibration file, not a stages file"):
        read_record(write_record(tmp_path / "c.json", "calibration", {}), "stages")
    assert read_record(tmp_path / "c.json", "calibration") == {}


def test_a_calibration_of_another_format_is_refused_by_the_commands_that_read_it(tmp_path, capsys):
    from detector.cli import main

    newer = tmp_path / "calibration.json"
    newer.write_text(json.dumps({**stamped("calibration", {}), "format": 2, "written_by": "poles 0.2.0"}))
    assert main(["evaluate", "--data", str(tmp_path), "--model", "colour-filter", "--calibration", str(newer),
                 "--out", str(tmp_path / "ev")]) == 2
    assert "calibration format 2, written by poles 0.2.0" in capsys.readouterr().err


if __name__ == "__main__":  # write the fingerprints of today's fields: only together with a moved format number
    current = {kind: [FORMATS[kind], _fingerprint(spec)] for kind, spec in _records().items()}
    SNAPSHOT.parent.mkdir(exist_ok=True)
    SNAPSHOT.write_text(json.dumps(current, indent=1, sort_keys=True) + "\n")
    print(f"wrote {SNAPSHOT}", file=sys.stderr)
