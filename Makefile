# Every target sets itself up on a fresh machine: it creates .venv and installs the project
# (runtime + training + test extras) the first time, and again whenever pyproject.toml changes.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: install demo test bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[train,test]'
	# donkeycar's own tub reader checks `export-drive --format tub` (tests/test_tub_export.py);
	# without its dependencies (TensorFlow and more), only what reading a tub imports
	$(PY) -m pip install --quiet --no-deps donkeycar==5.3.0 pyfiglet==1.0.4 prettytable==3.19.0 wcwidth==0.9.4
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/signlane demo --out out/demo

test: $(STAMP)
	$(PY) -m pytest -q

bench: $(STAMP)
	$(PY) benchmarks/render.py
	$(PY) benchmarks/lanes.py

clean:
	rm -rf out .pytest_cache
