# The two commands a newcomer needs: `make demo` (main job) and `make test`.
# Both create .venv if absent and install pasta with the tested pins in constraints.txt.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
# extras installed with pasta: dev (pytest, hypothesis, ruff, mypy). CI (.ci/run) sets EXTRAS=dev,ray so that the Ray
# backend's tests run there; `make demo` and a newcomer's `make test` do not need Ray (those tests skip).
EXTRAS ?= dev
comma := ,
STAMP := $(VENV)/.installed-$(subst $(comma),-,$(EXTRAS))

.PHONY: install demo train lint test test-all clean

install: $(STAMP)

$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade "pip>=23"
	$(PY) -m pip install --quiet -c constraints.txt -e ".[$(EXTRAS)]"
	touch $(STAMP)

# crs on the first fixed test config with the shipped weights: plan (exhaustive), execute with the learned
# policies, score; writes out/demo/run.mcap (Foxglove, `pasta replay`) and out/demo/summary.png.
# DEMO_ARGS="execute.controller=heuristic" executes with the heuristic controllers instead (later keys win).
DEMO_ARGS ?=

demo: $(STAMP)
	$(PY) -m pasta run task=crs seed=1000 execute.controller=learned log=out/demo/run.mcap summary=out/demo/summary.png $(DEMO_ARGS)

# Retrain every module (demos -> vae -> feasibility -> cost -> policies -> cut reset pose -> stopping rules);
# resumable. See `pasta pipeline --help`.
TRAIN_ARGS ?=

train: $(STAMP)
	$(PY) -m pasta pipeline $(TRAIN_ARGS)

# ruff (the rules in pyproject's [tool.ruff.lint]) and mypy ([tool.mypy]; its cache is .mypy_cache): both run,
# a finding of either fails
lint: $(STAMP)
	status=0; $(VENV)/bin/ruff check pasta plugins pasta_dough || status=1; $(PY) -m mypy || status=1; exit $$status

test: $(STAMP)
	$(PY) -m pytest -m "not slow" -q

test-all: $(STAMP)
	$(PY) -m pytest -q

clean:
	rm -rf $(VENV) build *.egg-info .mypy_cache .ruff_cache
