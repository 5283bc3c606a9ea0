# Two commands set up everything on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CC     ?= gcc
CFLAGS_STRICT := -std=c89 -Wall -Wextra -pedantic -Werror -O2
CSRC   := csrc/checksum.c csrc/framer.c csrc/ring.c csrc/align.c csrc/pingpong.c

.PHONY: venv demo test test-c asan valgrind bench lint soak clean

$(STAMP): pyproject.toml setup.py $(CSRC) csrc/robocli_core.h csrc/build_core.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,lint]'
	touch $@

venv: $(STAMP)

demo: $(STAMP)
	$(PY) examples/demo.py

test: $(STAMP) test-c
	$(PY) -m pytest -q -p no:cacheprovider --benchmark-disable -m "not slow"

# C tests read the golden vectors in specs/; warnings are errors.
csrc/test_core: $(CSRC) csrc/test_core.c csrc/robocli_core.h
	$(CC) $(CFLAGS_STRICT) -D_POSIX_C_SOURCE=200112L -Icsrc -o $@ csrc/test_core.c $(CSRC) -lpthread -lm

test-c: csrc/test_core
	./csrc/test_core specs

asan:
	$(CC) -std=c89 -Wall -Wextra -pedantic -Werror -g -O1 -fsanitize=address,undefined \
	  -fno-omit-frame-pointer -fno-sanitize-recover=all -D_POSIX_C_SOURCE=200112L -Icsrc \
	  -o csrc/test_core_asan csrc/test_core.c $(CSRC) -lpthread -lm
	ASAN_OPTIONS=detect_leaks=1 ./csrc/test_core_asan specs

valgrind: csrc/test_core
	valgrind --error-exitcode=1 --leak-check=full -q ./csrc/test_core specs

bench: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider bench --benchmark-columns=min,median,mean,ops,rounds

lint: $(STAMP)
	$(VENV)/bin/ruff check robocli tests bench examples
	$(VENV)/bin/mypy robocli

soak: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider -m slow --timeout=1200 tests

clean:
	rm -rf $(VENV) build *.egg-info robocli/_core*.so robocli/_core.c csrc/test_core csrc/test_core_asan
