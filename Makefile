# Two commands do all set-up on a fresh machine (Python 3.11, pip, gcc):
#   make demo   create .venv if missing, install, run the main job end to end (no root needed)
#   make test   same set-up plus a headless browser (apt, once), then the whole test suite
# DDS stays on this host; each run picks a domain of its own unless ROS_DOMAIN_ID is set.
# A user's own ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_DISCOVERY_SERVER or ROS_DOMAIN_ID is kept.
VENV    ?= .venv
PYTHON  ?= python3
PY      := $(VENV)/bin/python
STAMP   := $(VENV)/.installed
DEMO_JOB ?= config/jobs/drill_row.yaml
ifeq ($(strip $(ROS_DISCOVERY_SERVER)),)
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
endif

.PHONY: setup browser demo cell-demo test bench bench-peer bench-shop soak stress stream-lead clean

# The virtual environment with everything from PyPI: all that the demos and benchmarks need.
setup: $(STAMP)

# Headless Chromium (Debian's package) renders report.html in the tests only; installed once.
browser:
	@command -v chromium >/dev/null 2>&1 || { echo "installing chromium (apt)"; \
	  export DEBIAN_FRONTEND=noninteractive; apt-get update -qq >/dev/null && \
	  apt-get install -y -qq --no-install-recommends chromium fonts-liberation >/dev/null; }

$(STAMP): requirements.txt src/cnc_msgs_py/setup.py src/cnc_analysis/setup.py src/cnc_planner/setup.py src/cnc_servo_bridge/setup.py \
          src/cnc_servo_bridge/cnc_servo_bridge/_drive_kernel.c \
          $(wildcard src/cnc_planner/cnc_planner/*.h src/cnc_planner/cnc_planner/*/*.c src/cnc_planner/cnc_planner/*/*/*.c)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	$(PY) -m pip install --quiet --no-deps -e src/cnc_msgs_py -e src/cnc_analysis -e src/cnc_servo_bridge -e src/cnc_planner
	touch $(STAMP)

demo: setup
	$(VENV)/bin/cnc-run $(DEMO_JOB) --out runs/$$(date +%Y%m%d-%H%M%S)

# A cell: two mills and a lathe at once, one DDS domain, each under /cell/m<i>/cnc.
cell-demo: setup
	$(VENV)/bin/cnc-cell config/jobs/drill_row.yaml config/jobs/move_mill3.yaml \
	  config/jobs/thread_m12.yaml --out runs/cell-$$(date +%Y%m%d-%H%M%S)

test: setup browser
	$(PY) -m pytest

bench: setup
	$(PY) bench/run_all.py

# Side by side with LinuxCNC 2.9 (installs Debian's linuxcnc-uspace with apt-get if missing,
# runs it as an unprivileged user): not part of `make test`; about 6 minutes.
bench-peer: setup
	$(PY) bench/peer/run.py

# 12 simulated mills over 4 hosts in network namespaces (needs root), with Fast DDS's
# discovery server and with simple discovery: not part of `make bench`; about 8 minutes.
bench-shop: setup
	$(PY) bench/shop_floor.py

# A 10,000-hole plate and a 1-hour raster streamed over topics and checked from their
# recordings: not part of `make bench`; about 7 minutes on 2 idle CPUs (more under load).
soak: setup
	$(PY) bench/soak.py

# The real-time tests 50 times in a row beside two busy processes and the rest of the
# suite (restarted whenever it ends): not part of `make test`; one run takes 20-35 s on 2 CPUs,
# so about 20-30 minutes.
stress: setup
	$(PY) bench/stress_real_time.py --runs 50

# The stream's margin while long paths are planned beside a real-time job, under the same
# load: not part of `make bench`; about 5 minutes.
stream-lead: setup
	$(PY) bench/stream_lead.py

clean:
	rm -rf $(VENV) runs build install log
