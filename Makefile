# Two commands do all set-up on a fresh machine:  make demo   and   make test
# Every process started from here keeps DDS discovery on this machine.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
# Fast DDS over UDP on the loopback: its shared-memory transport hung nodes now and then.
export FASTDDS_BUILTIN_TRANSPORTS ?= UDPv4
export PYTHONUNBUFFERED := 1
# Python's byte-code cache stays on for all run from here, though a shell may set
# PYTHONDONTWRITEBYTECODE: without it each test worker, node and command compiles
# every module it imports again (collecting the tests took 12.9 s against 6.9 s).
unexport PYTHONDONTWRITEBYTECODE

VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: venv params demo reproduce accuracy mv-verdict mv-probes robustness gaps probes shared-cycles detector cnn cnn-large cnn-large-tune test fuzz lint bench bench-detector bench-explain bench-load bench-all colcon clean

# The demo: Table 2.1's undershoot case as a live loop of ROS 2 nodes on a
# lockstep sim clock at 100x real time, recorded to out/demo_bag, then analysed
# (out/demo_report.html).  Then a loop whose valve hides one effect
# (config/hidden_effect_loop.yaml), live and recorded, and --explain on the bag
# names the effect and prints the held-out MSE before and after
# (out/hidden_report.html).
DEMO_CASE ?= undershoot

venv:
	@bash tools/bootstrap.sh
	@$(PY) -m stiction_ros.cli.precompile --if-stale

# Regenerate config/params/<loop>_<case>/<node>.params.yaml from the loop files in config/
# (test_param_load fails when they are stale).
params: venv
	$(PY) -c 'from stiction_ros.sim.ros_params import write_shipped_node_params as w; w("config")'

demo: venv
	rm -rf out/demo_bag out/demo_bag.logs
	$(PY) -m stiction_ros.cli.loop config/concentration_loop.yaml --case $(DEMO_CASE) \
	  --rtf 100 --record out/demo_bag --json out/demo_summary.json
	$(PY) -m stiction_ros.cli.analyze out/demo_bag --json out/demo_report.json \
	  --html out/demo_report.html
	@echo '--- part 2: a valve hiding an effect; why does the plain model miss? ---'
	rm -rf out/hidden_bag out/hidden_bag.logs
	$(PY) -m stiction_ros.cli.loop config/hidden_effect_loop.yaml --rtf 100 \
	  --record out/hidden_bag --json out/hidden_summary.json
	$(PY) -m stiction_ros.cli.analyze out/hidden_bag --explain --json out/hidden_report.json \
	  --html out/hidden_report.html

reproduce: venv
	$(PY) -m stiction_ros.cli.study --out docs

# NumPy's code for a processor with AVX2 and no AVX-512, whatever the host, where
# the figures' last bits matter (stiction_ros/_blas.py; its AVX2 exp is slower).
# (NumPy 2.4's names for its x86 targets above AVX2; elsewhere nothing is set.)
NUMPY_ABOVE_AVX2 := X86_V4 AVX512_ICL AVX512_SPR
PINNED := $(if $(filter x86_64 amd64,$(shell uname -m)),NPY_DISABLE_CPU_FEATURES='$(NUMPY_ABOVE_AVX2)')

# The verdict on held-out data: the shared plant loops by valve tag, and simulated
# loops whose seeds training never saw; every method beside the old rule (about 10 min).
accuracy: venv
	$(PINNED) $(PY) -m stiction_ros.cli.accuracy ../shared/data/plant_loops --reports out/plant_loops \
	  --markdown docs/ACCURACY.md --json docs/accuracy.json

# The headline verdict with a measured valve position (the fits', not the detector's) on
# loops hiding stiction, play or a frictionless instrument effect, beside the rule it
# replaced (docs/MV_VERDICT.md; about 2 min on 2 cores: 120 s measured 2026-12-07).
mv-verdict: venv
	$(PINNED) $(PY) -m stiction_ros.cli.mv_verdict --markdown docs/MV_VERDICT.md \
	  --json docs/mv_verdict.json

# The same verdict on loops whose position reading carries effects the rule was never set
# on (a historian's deadband, drift, a held reading, two lags, a valve characteristic,
# windup, ...), each with a frictionless and a sticky valve (docs/MV_PROBES.md; about
# 4 min on 2 cores).
mv-probes: venv
	$(PINNED) $(PY) -m stiction_ros.cli.mv_probes --markdown docs/MV_PROBES.md \
	  --json docs/mv_probes.json

# The verdict on simulated loops read with PV damped after the controller, skewed clocks,
# historian compression, a coarser grid and without the set point, beside the same loops
# as simulated (docs/ROBUSTNESS.md; about 65 min on 2 cores: 3 870 s, with the set-point
# row and beside the test suite, in the run of 2026-12-06 that docs/ROBUSTNESS.md reports;
# 2 254 s the same day before that row).
robustness: venv
	$(PINNED) $(PY) -m stiction_ros.cli.robustness --markdown docs/ROBUSTNESS.md \
	  --json docs/robustness.json

# Simulated loops cut by a gap, judged on the longest stretch and on every stretch pooled
# (docs/GAPS.md; about 17-20 min on 2 cores: 1 031 s measured 2026-12-06).
gaps: venv
	$(PINNED) $(PY) -m stiction_ros.cli.gaps --markdown docs/GAPS.md --json docs/gaps.json

# The verdict on loops the simulator never draws: equal-percentage valves tuned hot,
# gap and error-squared level controllers, loops detuned past stability, controllers
# run 3-10 times per historian sample (docs/PROBES.md; 6-10 min on 2 cores).
probes: venv
	$(PINNED) $(PY) -m stiction_ros.cli.probes --markdown docs/PROBES.md --json docs/probes.json

# A sticky loop's cycle carried into a healthy loop: does the batch analyzer's shared-cycle
# view name the sticky one?  docs/SHARED_CYCLES.md, 3-7 min on 2 cores.
shared-cycles: venv
	$(PINNED) $(PY) -m stiction_ros.cli.shared_cycles --markdown docs/SHARED_CYCLES.md \
	  --json docs/shared_cycles.json --figure docs/figures/shared_cycles.png

# Rebuild the learned stiction detector from simulated loops alone (fixed seeds):
# stiction_ros/resources/stiction_detector.npz.  About 22-33 min on 2 cores from scratch
# (the figures of 7 500 simulated records, the slip footprints of their sticky records and
# the large network's logits of both sets), 1-2 min once out/detector_cache holds them.
detector: venv
	$(PINNED) $(PY) -m stiction_ros.cli.detector

# Retrain the detector's 1-D CNN (stiction_ros/resources/stiction_cnn.npz) on its own
# simulated corpus, about 15 min on 2 cores (corpus 129 s, training 774 s measured
# 2026-11-29); needs PyTorch (CPU), installed here.
# Trains on a CUDA GPU when PyTorch sees one (make cnn CNN_ARGS='--jobs 16 --seeds 300000').
# Then `make detector`: the network's logit is one of the detector's figures.
cnn: venv
	$(PY) -m pip install --quiet -r requirements/train.txt
	$(PY) -m stiction_ros.cli.cnn $(CNN_ARGS)

# Retrain the large network the detector's last step weighs in, in two steps.
# cnn-large: 600 000 corpus seeds, 5-8 min on one H200 with 16 cores (hours on 2 cores;
# epochs of 15 s in 2026-11-27, 26-30 s in 2026-11-29 and 22-31 s in 2026-11-30 on
# other leases) (stiction_ros/resources/stiction_cnn_large_base.npz). cnn-large-tune:
# that network trained on from its weights on 10 000 fresh seeds without the sticky
# records a deadband explains, on 2 cores 11.4 min in 2026-11-30 and 52 in 2026-11-29,
# each beside a make detector (stiction_cnn_large.npz, the one the detector reads).
# Then `make detector`.
cnn-large: venv
	$(PY) -m pip install --quiet -r requirements/train.txt
	$(PY) -m stiction_ros.cli.cnn --seeds 600000 --epochs 10 --batch 256 \
	  --out stiction_ros/resources/stiction_cnn_large_base.npz $(CNN_ARGS)

cnn-large-tune: venv
	$(PY) -m pip install --quiet -r requirements/train.txt
	$(PY) -m stiction_ros.cli.cnn --first-seed 3200000 --seeds 10000 --epochs 3 --batch 64 \
	  --peak-lr 3e-4 --without-deadband-like --jobs 2 \
	  --init stiction_ros/resources/stiction_cnn_large_base.npz \
	  --out stiction_ros/resources/stiction_cnn_large.npz $(CNN_ARGS)

# The tests run on two workers (pytest-xdist), a test file whole in one, the files that
# hold a slow test first (conftest), so that the run ends on short files.  Those that
# start ROS nodes (marker `ros`) run beside the others, each worker on its own ROS domain
# (conftest) and with its waits stretched 3x (ros_helpers.SLACK): there the waits took
# up to 0.66 of the unstretched limit.  One run of both kinds fills the cores that the
# nodes' waits leave idle (21 % of the ROS tests' 250 s run alone).  Last, one at a
# time, the `alone` ones: a node under SCHED_FIFO takes a core, the clock-fault test
# counts samples that a busy machine lets pass (its nodes took 13-19 s to start beside
# CPU-bound tests), and a valve killed and respawned beside another file left no gap in
# one CI run.  The slowest tests are listed at the end of each part: the suite must stay
# under 15 min on 2 cores.
TEST_JOBS ?= 2
# The files that hold an `alone` test, so that their run collects no others
# (test_make_test checks the list against the marks).
ALONE_TESTS := test/test_clock_faults.py test/test_realtime.py test/test_restart.py
test: venv
	$(PY) -m pytest -q -n $(TEST_JOBS) --dist loadfile -m 'not alone' --durations=20 test
	$(PY) -m pytest -q -m 'ros and alone' --durations=5 $(ALONE_TESTS)

# The input fuzz suite with fresh random inputs, 1 500 per test (CI runs 120, always the same).
fuzz: venv
	FUZZ_EXAMPLES=1500 FUZZ_RANDOM=1 $(PY) -m pytest -q test/test_fuzz_inputs.py

lint: venv
	$(PY) -m pytest -q test/test_flake8.py test/test_pep257.py

bench: venv
	$(PY) -m bench.run_all

# The learned stiction detector's cost per plant loop against the old signature
# vote (about a minute): its section of docs/BENCHMARKS.md.
bench-detector: venv
	$(PY) -m bench.detector_bench

# --explain run blind on concealed closed-loop cases, on scoring seeds nothing was tuned
# on (about 4 min on 2 cores: 2.5 min and 1.1 min in the run of 2026-11-27): the friction effects (65 cases), then the instrument and
# timing effects at 0.1-5 s sampling (52 runs); writes docs/EXPLAIN_BENCHMARK.md,
# docs/explain_bench.json and docs/instrument_bench.json.
bench-explain: venv
	$(PY) -m bench.explain_bench --seed-offset 900000
	$(PY) -m bench.instrument_bench --seeds-from 700000

# 20 loops of 3 node processes recorded into one bag for 10 min, at 10 Hz and again at
# 1 s, each after a 1-loop baseline (about 30 min): the load section of docs/BENCHMARKS.md.
bench-load: venv
	$(PY) -m bench.load_bench

# Every benchmark: speed, --explain's accuracy and load, about 70 min.
bench-all: bench bench-explain bench-load

colcon: venv
	$(VENV)/bin/colcon build --base-paths . --build-base /tmp/stiction_ros_colcon/build \
	  --install-base /tmp/stiction_ros_colcon/install

clean:
	rm -rf $(VENV) build install log .pytest_cache
