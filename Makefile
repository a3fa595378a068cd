# The two commands of the README, and a few more for developers.
#   make demo   bootstrap, build, run the main pipeline on the simulated sensor
#   make test   bootstrap, build, run every test (ctest)
SHELL := /bin/bash
JOBS ?= 2

.PHONY: demo test build bootstrap asan tsan fuzz bench docs clean lint format

bootstrap:
	@scripts/bootstrap

build: bootstrap
	@cmake --preset default >/dev/null
	@cmake --build --preset default -j $(JOBS)

test: build
	@ctest --preset default -j $(JOBS)

demo: build
	@scripts/demo

# Sanitizer builds of the bus, the messages, bags and the parsers.
asan: bootstrap
	@cmake --preset asan >/dev/null
	@cmake --build --preset asan -j $(JOBS)
	@ctest --preset asan -j $(JOBS)

tsan: bootstrap
	@cmake --preset tsan >/dev/null
	@cmake --build --preset tsan -j $(JOBS)
	@TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" ctest --preset tsan -j $(JOBS)

fuzz: bootstrap
	@cmake --preset fuzz >/dev/null
	@cmake --build --preset fuzz -j $(JOBS)

bench: build
	@scripts/run_benchmarks

# The style kept by machine: format, function size, clang-tidy (scripts/lint).
lint: build
	@scripts/lint

# Reformat the tree in place with .clang-format.
format: bootstrap
	@scripts/lint fix

clean:
	rm -rf build build-asan build-tsan build-fuzz
