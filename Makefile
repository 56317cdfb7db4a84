# Two commands for a fresh machine: `make demo` and `make test`. Both set up .venv first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test bench clean pole-model

setup: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	# torch and torchvision first, from the machine's local wheels (a CUDA build that runs on the CPU).
	$(BIN)/python -m pip install -q torch==2.14.1 torchvision==0.29.1
	$(BIN)/python -m pip install -q -e '.[train,test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/poles demo --out runs/demo

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

# The benchmarks also compare OpenVINO (and its NNCF INT8) with onnxruntime: an extra, not a runtime dependency.
bench: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[bench]'
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf runs .pytest_cache

# The shipped pole model's recipe (README, "The shipped pole model"). BACKGROUNDS: real frames without poles.
# The training step took 23 minutes on one H100 (--device 0); on a two-core CPU it takes days.
BACKGROUNDS ?= ../shared/real-backgrounds
DEVICE ?= cpu
POLE_TRAIN = --model yolov8n-seg --imgsz 640 --batch 64 --workers 14 --patience 100 --device $(DEVICE)
pole-model: $(STAMP)
	$(BIN)/poles synth --out runs/pole-data --images 8000 --seed 2026 --backgrounds $(BACKGROUNDS) --backdrop-share 0.75
	# Three chained runs (the GPU lease ran commands of at most 10 minutes): scratch, then fine-tuned twice.
	$(BIN)/poles train --data runs/pole-data --out runs/pole-model-1 --weights scratch $(POLE_TRAIN) --time 0.105
	$(BIN)/poles train --data runs/pole-data --out runs/pole-model-2 --weights runs/pole-model-1/weights/last.pt \
		$(POLE_TRAIN) --time 0.135
	$(BIN)/poles train --data runs/pole-data --out runs/pole-model --weights runs/pole-model-2/weights/last.pt \
		$(POLE_TRAIN) --time 0.118
	$(BIN)/poles synth --out runs/pole-tune --images 400 --seed 79 --backgrounds $(BACKGROUNDS) --backdrop-share 0.75
	$(BIN)/poles synth --out runs/pole-calib --images 135 --seed 5 --calibration-shots
	$(BIN)/poles export --weights runs/pole-model/weights/best.pt --out runs/pole-model/poles-yolov8n-seg.onnx \
		--data runs/pole-tune --int8 --dynamic --force
	$(BIN)/poles calibrate --data runs/pole-calib --out runs/pole-model/calibration.json \
		--model runs/pole-model/poles-yolov8n-seg.onnx --force
	$(BIN)/poles evaluate --model runs/pole-model/poles-yolov8n-seg.onnx --data runs/pole-tune --conf 0.5 \
		--out runs/pole-model/tune
	$(BIN)/python -m export.ship --weights runs/pole-model/weights/best.pt --onnx runs/pole-model/poles-yolov8n-seg.onnx \
		--calibration runs/pole-model/calibration.json \
		--conf $$($(BIN)/python -c "import json; print(json.load(open('runs/pole-model/tune/metrics.json'))['best_f1_conf'])")
