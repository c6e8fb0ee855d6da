# horizonreg: `make demo` installs what is missing, builds and runs the demo;
# `make test` builds and runs every test.
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

.PHONY: all deps test-deps build demo test bench asan asan-unit tsan clean

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
SAN_FLAGS = -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHORIZONREG_PYTHON=OFF
TSAN_TESTS = util_thread_pool_test horizon_horizon_test match_match_test pipeline_register_photo_test pipeline_batch_test
asan-unit: test-deps
	cmake -S . -B build-asan $(SAN_FLAGS) -DHORIZONREG_SANITIZE=ON
	cmake --build build-asan -j $(JOBS)
	cd build-asan && UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS) -R '_test$$'

tsan: test-deps
	cmake -S . -B build-tsan $(SAN_FLAGS) -DHORIZONREG_TSAN=ON
	cmake --build build-tsan -j $(JOBS) --target $(TSAN_TESTS)
	cd build-tsan && TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$(CURDIR)/tests/tsan.supp ctest --output-on-failure \
	  -R 'util/thread_pool_test|horizon/horizon_test|match/match_test|pipeline/register_photo_test|pipeline/batch_test'

clean:
	rm -rf $(BUILD) build-asan build-tsan out
