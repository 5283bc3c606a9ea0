# Two commands set up everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CC     ?= gcc
CFLAGS_STRICT := -std=c89 -Wall -Wextra -pedantic -Werror -O2
CSRC   := csrc/checksum.c csrc/framer.c csrc/ring.c csrc/align.c csrc/pingpong.c csrc/benchnet.c

.PHONY: venv demo test test-load test-c asan valgrind bench lint soak dist dist-check clean fuzz

$(STAMP): pyproject.toml setup.py $(CSRC) csrc/robocli_core.h csrc/netio.h csrc/build_core.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,lint]'
	touch $@

venv: $(STAMP)

demo: $(STAMP)
	$(PY) examples/demo.py

PYTEST := $(PY) -m pytest -q -p no:cacheprovider --benchmark-disable -m "not slow"
PYTEST_ARGS ?=

test: $(STAMP) test-c
	$(PYTEST) $(PYTEST_ARGS)

# The same suite with the CPU oversubscribed: LOAD_PER_CORE busy loops per core run beside it.
# The loops are killed when pytest ends, fails or is interrupted, and each one is bounded by
# `timeout` (LOAD_TIMEOUT s) in case make itself is killed. Tests assert behaviour, not speed:
# this must pass.
LOAD_PER_CORE ?= 2
LOAD_TIMEOUT  ?= 3600
test-load: $(STAMP) test-c
	@n=$$(( $$(nproc) * $(LOAD_PER_CORE) )); pids=; \
	stop() { for p in $$pids; do kill $$p 2>/dev/null; done; wait $$pids 2>/dev/null; pids=; }; \
	trap 'stop' EXIT; trap 'stop; exit 130' INT; trap 'stop; exit 143' TERM HUP; \
	for i in $$(seq $$n); do \
	  timeout $(LOAD_TIMEOUT) $(PY) -c 'while True: pass' & pids="$$pids $$!"; \
	done; \
	echo "test-load: $$n busy loops ($(LOAD_PER_CORE) per core) beside pytest"; \
	start=$$(date +%s); rc=0; $(PYTEST) $(PYTEST_ARGS) || rc=$$?; \
	stop; echo "test-load: pytest exit $$rc after $$(( $$(date +%s) - start )) s under load"; \
	exit $$rc

# C tests read the golden vectors in specs/; warnings are errors.
csrc/test_core: $(CSRC) csrc/test_core.c csrc/robocli_core.h csrc/netio.h
	$(CC) $(CFLAGS_STRICT) -D_POSIX_C_SOURCE=200112L -Icsrc -o $@ csrc/test_core.c $(CSRC) -lpthread -lm

# The benchmark peers (ping-pong, ARCOS responder) over real loopback sockets.
csrc/test_bench: $(CSRC) csrc/test_bench.c csrc/robocli_core.h csrc/netio.h
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
	$(PY) -m pytest -q -p no:cacheprovider bench --benchmark-columns=min,median,mean,ops,rounds

# The sdist alone must build the wheel (C sources, header and cffi script included), the
# wheel must be abi3, and it must work in a clean venv: version, then one simulator session.
# Needs only PyPI (build, the build requirements, the dependencies).
DIST_DIR ?= dist
dist:
	rm -rf $(DIST_DIR)/robocli-*
	$(PYTHON) -m venv $(DIST_DIR)/.buildenv
	$(DIST_DIR)/.buildenv/bin/pip install -q build
	$(DIST_DIR)/.buildenv/bin/python -m build --sdist --outdir $(DIST_DIR) .

dist-check: dist
	set -e; tmp=$$(mktemp -d); trap 'rm -rf "$$tmp"' EXIT; \
	$(DIST_DIR)/.buildenv/bin/pip wheel -q --no-deps -w "$$tmp" $(DIST_DIR)/robocli-*.tar.gz; \
	ls "$$tmp"/robocli-*-cp310-abi3-*.whl; \
	$(PYTHON) -m venv "$$tmp/venv"; \
	"$$tmp/venv/bin/pip" install -q "$$tmp"/robocli-*.whl; \
	cd "$$tmp"; \
	./venv/bin/robocli --version; \
	./venv/bin/robocli connect pioneer sim --once --json > session.json; \
	./venv/bin/python -c "import json; d = json.load(open('session.json')); print('session:', sorted(d)[:6])"

lint: $(STAMP)
	$(VENV)/bin/ruff check robocli tests bench examples
	$(VENV)/bin/mypy robocli

# Fuzzing (atheris): every harness of fuzz/ runs FUZZ_SECONDS seconds; a crash, an exception
# that is not a robocli error, a hang (FUZZ_TIMEOUT s on one input) or a memory blow-up
# (FUZZ_RSS_MB) fails. Findings land in build/fuzz/. `make fuzz FUZZ_SECONDS=600` for long runs.
FUZZ_SECONDS ?= 60
FUZZ_TIMEOUT ?= 10
FUZZ_RSS_MB  ?= 2048
FUZZ_TARGETS := framer-arcos framer-sm-le framer-sm-be framer-ros4mat \
                decode-arcos decode-simple_message decode-ros4mat
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

clean:
	rm -rf $(VENV) build dist *.egg-info robocli/_core*.so robocli/_core.c csrc/test_core csrc/test_core_asan csrc/test_bench csrc/test_bench_asan
