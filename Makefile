# horizonreg: `make demo` installs what is missing, builds and runs the demo;
# `make test` builds and runs every test.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps test-deps build demo test bench asan asan-unit tsan fuzz fuzz-build fuzz-replay clean

all: build

deps:
	@scripts/install_deps.sh

test-deps:
	@scripts/install_deps.sh --test

build: deps
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)
	cmake --build $(BUILD) -j $(JOBS)

demo: build
	$(BUILD)/horizonreg demo --output-dir out

test: test-deps build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

bench: build
	$(BUILD)/horizon_bench
	$(BUILD)/skyline_bench
	$(BUILD)/register_bench
	$(BUILD)/track_bench
	$(BUILD)/batch_bench
	scripts/bench_process.sh $(BUILD)/horizonreg
	scripts/bench_grass_points.sh $(BUILD)/horizonreg || [ $$? -eq 77 ]

asan: test-deps
	$(MAKE) test BUILD=build-asan CMAKE_FLAGS="-DCMAKE_BUILD_TYPE=RelWithDebInfo -DHORIZONREG_SANITIZE=ON"

# The unit tests (every module's *_test) under AddressSanitizer + UBSan, and
# the threaded code's tests under ThreadSanitizer: what .ci/run adds to `make test`.
# Line tables only (-g1): the sanitizers' stack traces keep file and line,
# and the builds take about 40% less (match/fit.cc under ASan: 86 s with -g,
# 51 s with -g1; the ASan build took 17 of a fresh clone's 89 minutes here on 2026-12-01).
SAN_FLAGS = -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHORIZONREG_PYTHON=OFF '-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG'
TSAN_TESTS = util_thread_pool_test horizon_horizon_test match_match_test pipeline_register_photo_test pipeline_batch_test \
  pipeline_locate_test
asan-unit: test-deps
	cmake -S . -B build-asan $(SAN_FLAGS) -DHORIZONREG_SANITIZE=ON
	cmake --build build-asan -j $(JOBS) --target unit_tests
	cd build-asan && UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS) -R '_test$$'

tsan: test-deps
	cmake -S . -B build-tsan $(SAN_FLAGS) -DHORIZONREG_TSAN=ON
	cmake --build build-tsan -j $(JOBS) --target $(TSAN_TESTS)
	cd build-tsan && TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$(CURDIR)/tests/tsan.supp ctest --output-on-failure -j $(JOBS) \
	  -R 'util/thread_pool_test|horizon/horizon_test|match/match_test|pipeline/register_photo_test|pipeline/batch_test|pipeline/locate_test'

# libFuzzer targets (fuzz/, clang, ASan + UBSan) in build-fuzz: `make fuzz`
# runs each for FUZZ_SECONDS (niced, one at a time) and prints execs/s and
# coverage; `make fuzz-replay` runs the seed corpus and the saved crash inputs
# once (seconds). FUZZ_TARGETS=dem picks targets.
FUZZ_SECONDS ?= 60
FUZZ_TARGETS ?= image dem exif sensors landmarks pose camera_file batch
FUZZ_JOBS ?= 2
fuzz-build:
	@scripts/install_deps.sh
	@scripts/install_deps.sh --fuzz
	cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DHORIZONREG_PYTHON=OFF -DHORIZONREG_WERROR=OFF -DHORIZONREG_FUZZ=ON
	cmake --build build-fuzz -j $(FUZZ_JOBS) --target $(addprefix fuzz_,$(FUZZ_TARGETS))

fuzz: fuzz-build
	scripts/run_fuzz.sh build-fuzz $(FUZZ_SECONDS) $(FUZZ_TARGETS)

fuzz-replay: fuzz-build
	scripts/run_fuzz.sh --replay build-fuzz $(FUZZ_TARGETS)

clean:
	rm -rf $(BUILD) build-asan build-tsan build-fuzz out
