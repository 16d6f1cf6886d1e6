# Every target installs what is missing first (a virtualenv in .venv), so each works on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
ARGS ?=

.PHONY: install compile train train-two-stage train-fast train-targets train-args test test-slow bench lint clean experiments-table3 experiments-moving report wheel-check

# The compilations of make train and of python -m agrl.train's defaults made ahead, as the last step of install, so
# that their first runs load them instead of compiling: one iteration of each (make train's on its processor path)
# into a folder thrown away after. torch.compile keeps what it made (the simulator in ~/.cache/agrl/compiled, the
# loss's kernels in torch's cache; docs/training.md, "The compiled simulator and warm starts"); a compilation that
# failed (agrl then runs eagerly) prints its warning. About 70 s on 2 cores the first time, 15 s once kept.
# `make compile` runs it again (after upgrading torch, or if torch's cache in /tmp was cleared).
define compile_train
	@echo "compiling the simulator and loss of make train and of the defaults ahead (about 70 s the first time)"
	@folder=$$(mktemp -d) && \
	  if $(SHIPPED_CPU_PATH) $(PY) -m agrl.train +experiment=switch_schedule ppo.total_frames=1 eval.episodes=32 \
	    progress=false hydra.run.dir=$$folder/train > $$folder/compile.log 2>&1 && \
	    $(PY) -m agrl.train ppo.total_frames=1 eval.episodes=32 progress=false hydra.run.dir=$$folder/defaults \
	    >> $$folder/compile.log 2>&1; \
	  then grep -h "RuntimeWarning" $$folder/compile.log >&2; rm -rf $$folder; \
	  else cat $$folder/compile.log >&2; rm -rf $$folder; exit 1; fi
endef

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip >/dev/null
	$(PY) -m pip install -e ".[dev,bench]"
	$(compile_train)
	touch $(STAMP)

install: $(STAMP)

compile: install
	$(compile_train)

# The main job on its defaults: the shipped baseline (docs/results/baseline.md), under a minute on 2 cores. One run
# (+experiment=switch_schedule): PPO from scratch at a switch cost of 0.104 until a periodic evaluation, confirmed on
# 1000 other episodes, reaches 99.8 %, then 60 iterations at 0.449 in the same run. ARGS: extra Hydra overrides
# (e.g. ARGS='seed=1'). Other tasks and methods: python -m agrl.train task=uniform speed=50 method=reuse (README).
TRAIN_DIR ?= runs/fixed/baseline/$(NOW)
NOW := $(shell date +%Y-%m-%d_%H-%M-%S)
train: install
	$(SHIPPED_CPU_PATH) $(PY) -m agrl.train +experiment=switch_schedule hydra.run.dir=$(TRAIN_DIR) $(ARGS)

# The processor path the shipped baseline was trained on: torch's AVX2 kernels (ATEN_CPU_CAPABILITY, which the code
# torch.compile generates follows) and MKL's (MKL_ENABLE_INSTRUCTIONS). A processor with AVX-512 runs them too, and
# make train then gives the shipped agent bit for bit there as well (docs/results/baseline.md, "Reproducibility and
# caveats"). Empty where the processor has no AVX2 (torch chooses); `make train CPU_PATH=` leaves it to torch anyway.
CPU_PATH ?= $(shell grep -qw avx2 /proc/cpuinfo 2>/dev/null && echo avx2)
SHIPPED_CPU_PATH := $(if $(CPU_PATH),ATEN_CPU_CAPABILITY=$(CPU_PATH) MKL_ENABLE_INSTRUCTIONS=$(shell echo $(CPU_PATH) | tr a-z A-Z))

# The shipped baseline until 2026-12-06, baseline-two-stage (Tables 4-5's B; docs/results/baseline.md): two stages.
# Stage 1 trains the fixed-destination agent from scratch at a switch cost of 0.1 until a periodic evaluation reaches
# 99.5 % (`python -m agrl.train`'s defaults, with the eager loss); stage 2 fine-tunes it at 0.3 for 80 iterations
# (+experiment=switch_finetune).
# ARGS: extra Hydra overrides for stage 1. FINETUNE_ARGS: for stage 2; its default is that agent's own stage 2,
# seed 1 on one torch thread (a run is bit for bit the same only at the same thread count). Its agent was trained on
# torch's AVX-512 path, which this target leaves torch to choose (checked on an AMD EPYC with AVX-512).
TWO_STAGE_DIR ?= runs/fixed/two_stage/$(NOW)
FINETUNE_ARGS ?= seed=1 threads=1
# The PPO loss run eagerly, as it was by default until 2026-12-07: the conditions in which the agents of
# train-two-stage and train-targets were trained and Tables 3-5 (experiments-*) measured.
EAGER_LOSS := ppo.compile_loss=false
train-two-stage: train-args install
	$(PY) -m agrl.train $(EAGER_LOSS) hydra.run.dir=$(TWO_STAGE_DIR)/stage1 $(ARGS)
	$(PY) -m agrl.train +experiment=switch_finetune $(EAGER_LOSS) method.baseline=$(TWO_STAGE_DIR)/stage1 \
	  hydra.run.dir=$(TWO_STAGE_DIR)/stage2 $(FINETUNE_ARGS)

# The same two stages in about half the training time, not the shipped recipe (docs/results/ppo_geometry.md, "Two fast
# stages"): stage 1 is +experiment=fast (2 x 64 networks, compiled loss, stricter stop) with make train's reward,
# stage 2 the same fine-tune on those networks with the compiled loss. Its agents fly about as few instructions as
# the shipped baseline, at a slightly lower success (figures in that page).
# ARGS: extra overrides for both stages (e.g. ARGS='seed=2').
FAST_TRAIN_DIR ?= runs/fixed/fast/$(NOW)
FAST_NETWORKS := 'agent.actor_hidden=[64,64]' 'agent.critic_hidden=[64,64]'
train-fast: train-args install
	$(PY) -m agrl.train +experiment=fast reward.use_continuous_action=false hydra.run.dir=$(FAST_TRAIN_DIR)/stage1 $(ARGS)
	$(PY) -m agrl.train +experiment=switch_finetune method.baseline=$(FAST_TRAIN_DIR)/stage1 $(FAST_NETWORKS) \
	  hydra.run.dir=$(FAST_TRAIN_DIR)/stage2 $(ARGS)

# The shipped target-holding agent, baseline-targets (docs/results/action_sets.md): make train-two-stage's two stages with
# actions=targets (heading, altitude and speed clearances flown by an autopilot; conf/actions/targets.yaml). Stage 1
# trains from scratch at a switch cost of 0.1 until a periodic evaluation reaches 99.5 %, stage 2 fine-tunes it at 0.3
# for 80 iterations; 2.5-4 min on 2 cores, the shipped file bit for bit on the AMD EPYC processors with AVX-512 it was
# checked on (it was trained on torch's AVX-512 path, so it leaves the path to torch; make train pins AVX2). ARGS:
# extra overrides for both stages (e.g. ARGS='seed=2').
TARGETS_TRAIN_DIR ?= runs/fixed/targets/$(NOW)
train-targets: train-args install
	$(PY) -m agrl.train actions=targets $(EAGER_LOSS) hydra.run.dir=$(TARGETS_TRAIN_DIR)/stage1 $(ARGS)
	$(PY) -m agrl.train actions=targets +experiment=switch_finetune $(EAGER_LOSS) \
	  method.baseline=$(TARGETS_TRAIN_DIR)/stage1 hydra.run.dir=$(TARGETS_TRAIN_DIR)/stage2 $(ARGS)

# Stage 2 of train-two-stage and train-fast fine-tunes stage 1's fixed-destination agent on its recipe's networks: stop at
# once if ARGS would give it another task, method or networks.
train-args:
	@case " $(ARGS) " in *" task="*|*" method="*|*" +experiment="*|*" agent."*) \
	  echo "make $(MAKECMDGOALS): ARGS='$(ARGS)' changes the task, method, experiment or networks, but its stage 2 fine-tunes the fixed-destination agent of its recipe's networks; allowed: other overrides (e.g. ARGS='seed=3'); for other tasks and methods run python -m agrl.train (README)" >&2; \
	  exit 2;; \
	esac

# The fast default suite (slow-marked tests excluded by pyproject's addopts).
test: install
	$(PY) -m pytest

# Build the wheel, install it into a fresh virtualenv and train / evaluate from outside the checkout.
wheel-check:
	PYTHON=$(PYTHON) bash .ci/wheel-check

# The slow suite: four real training runs with budgets in decisions (docs/training.md, "The slow suite").
test-slow: install
	$(PY) -m pytest -m slow -n 0

# The benchmarks beside the package (benchmarks/, not in the wheel), run from the repository root: one JSON object
# per line (docs/benchmarks.md). ARGS: extra options for benchmarks.bench (e.g. ARGS="--threads 1").
bench: install
	$(PY) -m benchmarks.bench $(ARGS)
	$(PY) -m benchmarks.bench_reuse
	$(PY) -m benchmarks.bench_peer --trainers agrl agrl-compiled stable-baselines3 floor floor-equal-work
	$(PY) -m benchmarks.startup

lint: install
	$(PY) -m ruff check agrl tests benchmarks

# The reproductions summarised in docs/results/ (hours of CPU; see those pages for the budgets used). Table 3's eighth
# row (runs/table3_stage2) fine-tunes the shipped stage-1 agent (checkpoint=baseline-stage1, python -m agrl.baselines).
# LAUNCHER picks Hydra's launcher: empty = one run at a time in this process (what the wall-time figures need),
# joblib = several local processes (hydra.launcher.n_jobs), submitit_slurm = Slurm jobs (see docs/training.md).
# Extra overrides in ARGS, e.g. make experiments-moving LAUNCHER=submitit_slurm ARGS="hydra.launcher.partition=cpu"
LAUNCHER ?=
SWEEP = $(if $(LAUNCHER),hydra/launcher=$(LAUNCHER)) $(ARGS)
MOVING := $(EAGER_LOSS) method.baseline=baseline-two-stage seed=0,1,2 ppo.max_minutes=3 target_success=0.99 progress=false
# 100 m/s, the hardest setting, also gets 8-minute runs.
MOVING_LONG := $(EAGER_LOSS) method.baseline=baseline-two-stage seed=0,1,2 ppo.max_minutes=8 target_success=0.99 progress=false
experiments-moving: install
	$(PY) -m agrl.train -m $(SWEEP) $(MOVING) task=uniform speed=10,20,50,100 method=scratch,pretrained,reuse hydra.sweep.dir=runs/moving/uniform
	$(PY) -m agrl.train -m $(SWEEP) $(MOVING) task=curved radius=500,1000,2000,5000 method=scratch,pretrained,reuse hydra.sweep.dir=runs/moving/curved
	$(PY) -m agrl.train -m $(SWEEP) $(MOVING) task=irregular method=scratch,pretrained,reuse hydra.sweep.dir=runs/moving/irregular
	$(PY) -m agrl.train -m $(SWEEP) $(MOVING_LONG) task=uniform speed=100 method=pretrained,reuse hydra.sweep.dir=runs/moving_long/uniform
	$(PY) -m agrl.train -m $(SWEEP) $(MOVING_LONG) task=uniform speed=100 method=reuse method.start_from_baseline=true hydra.sweep.dir=runs/moving_long/uniform

experiments-table3: install
	$(PY) -m agrl.train -m $(SWEEP) $(EAGER_LOSS) reward=none,continuous,position,both seed=0,1,2 ppo.max_minutes=5 progress=false hydra.sweep.dir=runs/table3
	$(PY) -m agrl.train -m $(SWEEP) $(EAGER_LOSS) reward=switch reward.use_continuous_action=true reward.switch_cost=0.1,0.3 seed=0,1,2 ppo.max_minutes=5 progress=false hydra.sweep.dir=runs/table3
	$(PY) -m agrl.train -m $(SWEEP) $(EAGER_LOSS) reward=switch seed=0,1,2 ppo.max_minutes=5 progress=false hydra.sweep.dir=runs/table3
	$(PY) -m agrl.train -m $(SWEEP) $(EAGER_LOSS) +experiment=switch_finetune method.baseline=baseline-stage1 seed=0,1,2 threads=1 progress=false hydra.sweep.dir=runs/table3_stage2

report: install
	$(PY) -m agrl.report pages

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
