# Two commands do all set-up on a fresh machine (Python 3.11, pip, gcc):
#   make demo   create .venv if missing, install, run the main job end to end
#   make test   same set-up, then the whole test suite
# DDS stays on this host; each run picks a domain of its own unless ROS_DOMAIN_ID is set.
VENV    ?= .venv
PYTHON  ?= python3
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
DEMO_JOB ?= config/jobs/drill_row.yaml
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

.PHONY: setup demo test bench clean

setup: $(STAMP)

$(STAMP): requirements.txt src/cnc_msgs_py/setup.py src/cnc_planner/setup.py src/cnc_servo_bridge/setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e src/cnc_msgs_py -e src/cnc_servo_bridge -e src/cnc_planner
	touch $(STAMP)

demo: setup
	$(VENV)/bin/cnc-run $(DEMO_JOB) --out runs/$$(date +%Y%m%d-%H%M%S)

test: setup
	$(PY) -m pytest

bench: setup
	$(PY) bench/run_all.py

clean:
	rm -rf $(VENV) runs build install log
