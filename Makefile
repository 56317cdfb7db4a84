# Two commands for a fresh machine: `make demo` and `make test`. Both set up .venv first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo test test-capped bench clean pole-model robot-model

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

# The runtime's tests again with numpy, OpenCV and oneDNN (OpenVINO, torch) capped at the Nao's Atom's instruction
# set as detector/speed.py caps them, so a kernel that answers differently there shows up here first.
CAPPED_TESTS = tests/test_frontend.py tests/test_robot_front_end.py tests/test_openvino_precision.py \
	tests/test_atom_graph.py tests/test_shipped_model.py
test-capped: $(STAMP)
	$(BIN)/python -c 'import subprocess, sys; from detector.speed import worker_environment; \
	sys.exit(subprocess.call([sys.executable, "-m", "pytest", "-q", "-n", "2", *sys.argv[1:]], \
	env=worker_environment(capped=True)))' $(CAPPED_TESTS)

# The benchmarks also compare OpenVINO (and its NNCF INT8) with onnxruntime: an extra, not a runtime dependency.
bench: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[bench]'
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf runs .pytest_cache

# The shipped accurate model's recipe (docs/model-card.md). BACKGROUNDS: real frames without poles.
# Stages 1, 2, 5 and 14 trained 23, 24, 18 and 18 minutes on one H100, stages 16, 17 and 19 about 6 minutes each on
# one H100 or H200 (DEVICE=0; on a two-core CPU they would take days); stages 3 and 4 trained 1.7 hours each on a
# two-core CPU.
BACKGROUNDS ?= ../shared/real-backgrounds
DEVICE ?= cpu
POLE_TRAIN = --model yolov8n-seg --imgsz 640 --batch 64 --workers 14 --patience 100 --device $(DEVICE)
POLE_SYNTH = --backgrounds $(BACKGROUNDS) --backdrop-share 0.75
# Model v7, the soup of v6 and its three GPU fine-tunes: its best.pt is what ships.
FINAL = runs/pole-model-v7
# Rendered walks whose frames measure a walking robot's range noise (not the seeds README's SLAM figures use).
WALKS = square circle figure8
WALK_SEEDS = 10 11 12
# Chained time-capped runs, each fine-tuned from the one before's last.pt (the GPU lease ran commands of at most
# 10 minutes): $(1) data, $(2) first weights, $(3) run folder prefix, $(4) hours of each run, $(5) seed.
chain = w=$(2); i=0; for h in $(4); do i=$$((i+1)); \
	$(BIN)/poles train --data $(1) --out $(3)-$$i --weights $$w $(POLE_TRAIN) --time $$h --seed $(5) || exit 1; \
	w=$(3)-$$i/weights/last.pt; done
# One short GPU fine-tune of v6 (stage 15's checkpoint) on 6,000 fresh frames: $(1) stage, $(2) seed, $(3) hours,
# $(4) extra `poles synth` options.
finetune_v6 = $(BIN)/poles synth --out runs/pole-data-$(1) --images 6000 --seed $(2) $(POLE_SYNTH) $(4) && \
	$(BIN)/poles train --data runs/pole-data-$(1) --out runs/pole-model-$(1) --weights runs/pole-model-15/weights/best.pt \
		$(POLE_TRAIN) --time $(3) --seed $(2)
pole-model: $(STAMP)
	# Stage 1 (model v1): from scratch on 8,000 frames (rendered at commit ae8c21a; later renderers draw other frames).
	$(BIN)/poles synth --out runs/pole-data-1 --images 8000 --seed 2026 $(POLE_SYNTH)
	$(call chain,runs/pole-data-1,scratch,runs/pole-model-1,0.105 0.135 0.118,0)
	# Stage 2 (model v2): fine-tuned from stage 1 on 10,000 frames of the renderer of commit c966f1a.
	$(BIN)/poles synth --out runs/pole-data-2 --images 10000 --seed 2030 $(POLE_SYNTH)
	$(call chain,runs/pole-data-2,runs/pole-model-1-3/weights/last.pt,runs/pole-model-2,0.085 0.14 0.11,2030)
	# Stage 3 (model v3): v2 fine-tuned on a two-core CPU on 4,000 frames whose varied paint fills the
	# colour filter's boxes (renderer of commit aab21d0), one 1.7-hour run.
	$(BIN)/poles synth --out runs/pole-data-3 --images 4000 --seed 2031 $(POLE_SYNTH)
	$(BIN)/poles train --data runs/pole-data-3 --out runs/pole-model-3 --weights runs/pole-model-2-3/weights/best.pt \
		--model yolov8n-seg --imgsz 640 --batch 16 --patience 100 --time 1.7 --seed 2031 --threads shared
	# Stage 4 (model v4): v3 fine-tuned the same way on 4,000 frames that label a pole only when both of its
	# coloured bands show (renderer of commit 40fa90f).
	$(BIN)/poles synth --out runs/pole-data-4 --images 4000 --seed 2032 $(POLE_SYNTH)
	$(BIN)/poles train --data runs/pole-data-4 --out runs/pole-model-4 --weights runs/pole-model-3/weights/best.pt \
		--model yolov8n-seg --imgsz 640 --batch 16 --patience 100 --time 1.7 --seed 2032 --threads shared
	# Stage 5 (model v5, shipped): v4 fine-tuned on one H100 for 0.3 hours (one run) on 12,000 fresh frames of the
	# same renderer.
	$(BIN)/poles synth --out runs/pole-data-5 --images 12000 --seed 2033 $(POLE_SYNTH)
	$(BIN)/poles train --data runs/pole-data-5 --out runs/pole-model-5 --weights runs/pole-model-4/weights/best.pt \
		$(POLE_TRAIN) --time 0.30 --seed 2033
	# Stage 14: v5 fine-tuned with its own recipe on 12,000 frames of the current renderer (one H100, 0.3 hours;
	# rendered at commit bbca580). Not shipped alone (rules v24, v25).
	$(BIN)/poles synth --out runs/pole-data-14 --images 12000 --seed 2042 $(POLE_SYNTH)
	$(BIN)/poles train --data runs/pole-data-14 --out runs/pole-model-14 --weights runs/pole-model-5/weights/best.pt \
		$(POLE_TRAIN) --time 0.30 --seed 2042
	# Stage 15 (model v6, shipped): no training, the weight-space blend 0.25 v5 + 0.75 stage 14 (rule v26; alpha
	# chosen among 0.25, 0.5 and 0.75 on the tuning set below).
	mkdir -p runs/pole-model-15/weights
	$(BIN)/poles soup --weights runs/pole-model-5/weights/best.pt runs/pole-model-14/weights/best.pt --alpha 0.75 \
		--out runs/pole-model-15/weights/best.pt --force
	# Stages 16, 17 and 19: v6 fine-tuned with its own recipe on 6,000 fresh frames each, the last two with every pole
	# of 30 % of the scenes 3-9 m away; each run as long as one 10-minute command on a lent GPU allowed.
	$(call finetune_v6,16,2043,0.1067,)
	$(call finetune_v6,17,2044,0.0969,--far-share 0.3)
	$(call finetune_v6,19,2045,0.0997,--far-share 0.3)
	# Model v7 (shipped): no training, the soup of v6 and stages 16, 17 and 19 in equal shares (rule v30).
	mkdir -p $(FINAL)/weights
	$(BIN)/poles soup --weights runs/pole-model-15/weights/best.pt runs/pole-model-16/weights/best.pt --alpha 0.5 \
		--out runs/soup-v6-16.pt --force
	$(BIN)/poles soup --weights runs/pole-model-17/weights/best.pt runs/pole-model-19/weights/best.pt --alpha 0.5 \
		--out runs/soup-17-19.pt --force
	$(BIN)/poles soup --weights runs/soup-v6-16.pt runs/soup-17-19.pt --alpha 0.5 --out $(FINAL)/weights/best.pt --force
	# The operating threshold: best F1 on all 400 frames of a separate tuning set (one split holds them all; v6's
	# was seed 99, v7's seed 139); its training frames calibrate the INT8 export.
	$(BIN)/poles synth --out runs/pole-tune --images 400 --seed 139 $(POLE_SYNTH)
	$(BIN)/poles split --data runs/pole-tune --out runs/pole-tune-all --ratios 0 0 1
	# 195 shots: every class at 0.5-9 m (13 distances) and 0, +-10, +-20 deg (rule v18, 2026-11-25; 135 shots at 0.5-5 m before).
	$(BIN)/poles synth --out runs/pole-calib --images 195 --seed 5 --calibration-shots
	$(BIN)/poles export --weights $(FINAL)/weights/best.pt --out $(FINAL)/poles-yolov8n-seg.onnx \
		--data runs/pole-tune --int8 --dynamic --force
	# The noise the filter is told: what the model's masks (and the colour filter's band distances) show in the frames of nine rendered walks.
	for walk in $(WALKS); do for seed in $(WALK_SEEDS); do \
		$(BIN)/poles synth --out runs/walknoise/$$walk-$$seed --walk $$walk --seed $$seed --force || exit 1; done; done
	$(BIN)/poles calibrate --data runs/pole-calib --out $(FINAL)/calibration.json \
		--model $(FINAL)/poles-yolov8n-seg.onnx --force \
		$(foreach walk,$(WALKS),$(foreach seed,$(WALK_SEEDS),--noise-data runs/walknoise/$(walk)-$(seed)))
	$(BIN)/poles evaluate --model $(FINAL)/poles-yolov8n-seg.onnx --data runs/pole-tune-all --split valid --conf 0.5 \
		--calibration $(FINAL)/calibration.json --out $(FINAL)/tune --force
	$(BIN)/python -m export.ship --weights $(FINAL)/weights/best.pt --onnx $(FINAL)/poles-yolov8n-seg.onnx \
		--calibration $(FINAL)/calibration.json \
		--conf $$($(BIN)/python -c "import json; print(json.load(open('$(FINAL)/tune/metrics.json'))['best_f1_conf'])")

# The robot front end's recipe (docs/robot-model.md): pink candidates at full resolution, a preclassifier and a crop
# network per candidate (`poles train-robot`), trained on this two-core CPU from rendered frames over real backdrops;
# its threshold the best F1 on a tuning set with each frame's camera pose, its range laws fitted on its own boxes.
# The shipped crop network is the 40-epoch run of the release before (its crops were area-averaged, this release's
# are sampled); its preclassifier is the second train-robot run below, on the frames of seeds 2070 and 2071.
ROBOT = runs/robot-front-end
ROBOT_SYNTH = $(POLE_SYNTH) --far-share 0.3
robot-model: $(STAMP)
	$(BIN)/poles synth --out runs/crops-data-1 --images 4000 --seed 2060 $(ROBOT_SYNTH)
	$(BIN)/poles synth --out runs/crops-data-2 --images 6000 --seed 2061 $(ROBOT_SYNTH)
	$(BIN)/poles train-robot runs/crops-data-1 runs/crops-data-2 --out $(ROBOT)-network --epochs 40 \
		--preclassifier-epochs 0 --force
	$(BIN)/poles synth --out runs/crops-data-p --images 2000 --seed 2070 $(ROBOT_SYNTH)
	$(BIN)/poles synth --out runs/crops-data-q --images 4000 --seed 2071 $(ROBOT_SYNTH)
	$(BIN)/poles train-robot runs/crops-data-p runs/crops-data-q --out $(ROBOT) --weights $(ROBOT)-network/poles-robot.pt \
		--epochs 0 --preclassifier-epochs 20 --force
	$(BIN)/poles synth --out runs/pole-tune-300 --images 300 --seed 139 $(POLE_SYNTH) --force
	$(BIN)/poles split --data runs/pole-tune-300 --out runs/pole-tune-300-all --ratios 0 0 1 --force
	$(BIN)/poles evaluate --model $(ROBOT)/poles-robot.onnx --data runs/pole-tune-300-all --split valid --pose \
		--out $(ROBOT)/tune --force
	$(BIN)/poles synth --out runs/pole-calib --images 195 --seed 5 --calibration-shots --force
	for walk in square-10 circle-11 figure8-12; do $(BIN)/poles synth --out runs/walknoise/$$walk \
		--walk $${walk%-*} --seed $${walk#*-} --force || exit 1; done
	$(BIN)/poles calibrate --data runs/pole-calib --out $(ROBOT)/calibration.json --model $(ROBOT)/poles-robot.onnx \
		--force --noise-data runs/walknoise/square-10 --noise-data runs/walknoise/circle-11 \
		--noise-data runs/walknoise/figure8-12
	$(BIN)/python -m export.ship --robot --weights $(ROBOT)/poles-robot.pt --onnx $(ROBOT)/poles-robot.onnx \
		--calibration $(ROBOT)/calibration.json \
		--conf $$($(BIN)/python -c "import json; print(json.load(open('$(ROBOT)/tune/metrics.json'))['best_f1_conf'])")
