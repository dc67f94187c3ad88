# Tessera - build, test, benchmark.
#
#   make            install missing Debian packages, build build/release/bin/tessera (make install: below)
#   make run        render the Cornell box and print where the image went
#   make test       build and run every test (ends with "N passed, N failed")
#   make test-asan  the tests under AddressSanitizer + UndefinedBehaviorSanitizer, leaks failing (LeakSanitizer), then test-lsan
#   make soak       the coordinator under load, hostile clients and kill -9 for SOAK_SECONDS (default 300)
#   make test-tsan  the threaded tests under ThreadSanitizer
#   make fuzz       libFuzzer targets, FUZZ_SECONDS each (default 20)
#   make stress     the numerical stress tests alone
#   make bench      speed and time-against-error figures, a few minutes once the
#                   references exist (printed, not asserted; tables and plots in bench/results/)
#   make bench-full the long version: ladders to 1024 spp, both benchmark scenes
#   make bench-reference  the converged references (cached in bench/ref/; ~20 min once)
#   make reference  regenerate tests/data/cornell-ref-64.pfm.gz (slow)

# Debian packages the build needs; `make deps` installs what is missing.
DEB_PACKAGES := gcc make pkg-config libcjson-dev libuv1-dev libjpeg-dev libopenexr-dev libpng-dev libsodium-dev \
                openexr openimageio-tools clang libclang-rt-14-dev gnuplot-nox libembree-dev qemu-user

SHELL := /bin/bash
CC ?= cc
VARIANT ?= release
BUILD := build/$(VARIANT)

# Determinism across hosts: no fast-math, no FMA contraction, no -march=native.
# (Add your own -march with EXTRA_CFLAGS; the bytes may then differ from other hosts.)
CFLAGS_COMMON := -std=c11 -D_DEFAULT_SOURCE -g -Wall -Wextra -Werror -ffp-contract=off -fno-fast-math \
                 -MMD -MP -iquote . -iquote common -I/usr/include/OpenEXR $(EXTRA_CFLAGS)
ifeq ($(VARIANT),asan)
  CFLAGS_OPT := -O1 -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=all
  LDFLAGS_V := -fsanitize=address,undefined
else ifeq ($(VARIANT),tsan)
  CFLAGS_OPT := -O1 -fsanitize=thread
  LDFLAGS_V := -fsanitize=thread
else
  CFLAGS_OPT := -O2
  LDFLAGS_V :=
endif
CFLAGS := $(CFLAGS_COMMON) $(CFLAGS_OPT) -I$(BUILD)
# The renderer's code at -O3 in the release build: 2-5% less render CPU
# than -O2 on the box and the icospheres, the same bytes (docs/meshes.md).
ifeq ($(filter asan tsan,$(VARIANT)),)
$(BUILD)/common/render/%.o: CFLAGS += -O3
endif
# Embree and Assimp are not linked: common/render/dynlib.c opens them on
# first use (a render that needs neither no longer loads them at start-up),
# by the sonames found here.
soname = $(shell objdump -p $$($(CC) -print-file-name=lib$(1).so) 2>/dev/null | awk '/SONAME/ {print $$2}')
$(BUILD)/common/render/dynlib.o: CFLAGS += -DTESSERA_EMBREE_SONAME='"$(or $(call soname,embree3),libembree3.so.3)"' \
                                           -DTESSERA_ASSIMP_SONAME='"$(or $(call soname,assimp),libassimp.so.5)"'
# The sanitizer builds link them all the same (dynlib.c then finds them
# already loaded): with Assimp dlopen()ed, LeakSanitizer's tracer crashed
# at the exit of farm processes (GCC 12's libsanitizer, glibc 2.36; one run
# in two of gltf_farm_same_bytes_any_workers_threads_tiles).
LINKED_AT_START := -Wl,--no-as-needed -lembree3 -lassimp
LDLIBS := -lcjson -lpng16 -ljpeg -lOpenEXRCore-3_1 -lsodium -luv -ldl -lpthread -lm \
          $(if $(filter asan tsan,$(VARIANT)),$(LINKED_AT_START))
LDFLAGS := $(LDFLAGS_V)

.DEFAULT_GOAL := all

# Layers (README "Where things are"): one static library per folder of
# common/, linked in this order (a library may use only those after it):
# job (what a job and a tile are on the wire) over render, image and net,
# all over base (common/*.c). scripts/layers.sh checks the #include lines.
LAYERS := job render image net base
layer_src = $(if $(filter base,$(1)),$(wildcard common/*.c),$(wildcard common/$(1)/*.c))
layer_lib = $(BUILD)/lib/libtessera_$(1).a
COMMON_SRC := $(foreach l,$(LAYERS),$(call layer_src,$(l)))
COMMON_OBJ := $(COMMON_SRC:%.c=$(BUILD)/%.o)
define LAYER_RULE
$(call layer_lib,$(1)): $(patsubst %.c,$(BUILD)/%.o,$(call layer_src,$(1)))
	@mkdir -p $$(dir $$@)
	@rm -f $$@ && ar rcs $$@ $$^
endef
$(foreach l,$(LAYERS),$(eval $(call LAYER_RULE,$(l))))
# What each program links, in layer order.
LIBS_ALL := $(foreach l,$(LAYERS),$(call layer_lib,$(l)))
LIBS_WORKER := $(foreach l,job render net base,$(call layer_lib,$(l)))
LIBS_LOADGEN := $(foreach l,job render net base,$(call layer_lib,$(l)))
TEST_SRC := $(wildcard tests/*.c)
TEST_OBJ := $(TEST_SRC:%.c=$(BUILD)/%.o)

TESSERA := $(BUILD)/bin/tessera
WORKER := $(BUILD)/bin/tessera-worker
COORD_OBJ := $(patsubst %.c,$(BUILD)/%.o,$(wildcard coordinator/*.c))
CLI_OBJ := $(patsubst %.c,$(BUILD)/%.o,$(wildcard cli/*.c))
WORKER_OBJ := $(patsubst %.c,$(BUILD)/%.o,$(wildcard worker/*.c))

# Peers of a farm must run the same code (docs/protocol.md): the handshake
# compares this id. Rewritten only when it changes, so it rebuilds nothing.
GIT_ID := $(shell git rev-parse --short=12 HEAD 2>/dev/null || echo nogit)$(shell git status --porcelain --untracked-files=no 2>/dev/null | grep -q . && echo -dirty)
TEST_BIN := $(BUILD)/bin/run-tests

.PHONY: all deps run test test-asan test-tsan stress bench bench-full bench-reference reference fuzz clean FORCE
all: $(TESSERA) $(WORKER)

build/%/build_id.h: FORCE
	@mkdir -p $(dir $@)
	@echo '#define TESSERA_BUILD_ID "$(GIT_ID)"' > $@.new
	@cmp -s $@.new $@ && rm -f $@.new || mv $@.new $@
$(BUILD)/common/net/protocol.o: $(BUILD)/build_id.h

DEPS_STAMP := build/.deps-ok
deps: $(DEPS_STAMP)
$(DEPS_STAMP): Makefile
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing missing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -ne 0 ] && SUDO=sudo; \
	  $$SUDO apt-get -o DPkg::Lock::Timeout=900 update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq -o DPkg::Lock::Timeout=900 $$missing \
	    || { echo "error: could not install:$$missing" >&2; exit 1; }; \
	fi
	@mkdir -p build && touch $@

$(BUILD)/%.o: %.c | $(DEPS_STAMP)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -c $< -o $@

# The local farm's forked workers (cli/local_fork.c) run worker/'s loop in
# the tessera binary: all of worker/ but its main.
WORKER_LIB_OBJ := $(filter-out $(BUILD)/worker/main.o,$(WORKER_OBJ))
$(TESSERA): $(CLI_OBJ) $(COORD_OBJ) $(WORKER_LIB_OBJ) $(LIBS_ALL)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)
	ln -sf tessera $(BUILD)/bin/tessera-coordinator

LOADGEN := $(BUILD)/bin/loadgen
$(LOADGEN): $(BUILD)/bench/loadgen.o $(LIBS_LOADGEN)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)

$(WORKER): $(WORKER_OBJ) $(LIBS_WORKER)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)

$(TEST_BIN): $(TEST_OBJ) $(BUILD)/coordinator/connlimit.o $(BUILD)/coordinator/joblog.o $(LIBS_ALL)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)

run: $(TESSERA) $(WORKER)
	@mkdir -p out
	$(TESSERA) render scenes/cornell-box.json -o out/cornell-box.png

# (walk-count by its path: WALK_COUNT is defined further down, after this rule is read)
test: $(TESSERA) $(WORKER) $(TEST_BIN) $(BUILD)/bin/walk-count
	TESSERA_BIN=$(TESSERA) $(TEST_BIN)

test-asan:
	$(MAKE) VARIANT=asan all build/asan/bin/run-tests build/asan/bin/walk-count
	@rm -rf $(ASAN_REPORTS) && mkdir -p $(ASAN_REPORTS)
	ASAN_OPTIONS=detect_leaks=1:log_path=$(CURDIR)/$(ASAN_REPORTS)/asan TESSERA_BIN=build/asan/bin/tessera build/asan/bin/run-tests; \
	rc=$$?; if compgen -G "$(ASAN_REPORTS)/*" > /dev/null; then rc=1; \
	  echo "test-asan: sanitizer reports (leaks or errors) from $$(ls $(ASAN_REPORTS) | wc -l) processes:"; head -40 $(ASAN_REPORTS)/*; fi; exit $$rc
	$(MAKE) test-lsan

# Numerical stress alone (also part of make test and test-asan).
stress: $(TESSERA) $(WORKER) $(TEST_BIN)
	TESSERA_BIN=$(TESSERA) $(TEST_BIN) --filter stress

# ThreadSanitizer on the tests that run several render threads. Embree builds
# on the calling thread here: its TBB workers synchronise in uninstrumented
# code, which TSan would report as races with our callbacks.
# The render threads (tests named *thread*), then the coordinator's work on
# libuv's thread pool: the dashboard's images and the finished image's
# write (tests/tsan.supp: a false positive of libuv's uninstrumented close).
test-tsan:
	$(MAKE) VARIANT=tsan build/tsan/bin/run-tests build/tsan/bin/tessera build/tsan/bin/tessera-worker
	TESSERA_EMBREE_CONFIG=threads=1 TESSERA_BIN=build/tsan/bin/tessera build/tsan/bin/run-tests --filter thread
	TSAN_OPTIONS=suppressions=$(CURDIR)/tests/tsan.supp TESSERA_BIN=build/tsan/bin/tessera \
	  build/tsan/bin/run-tests --filter http_dashboard_images_off_the_loop
	TSAN_OPTIONS=suppressions=$(CURDIR)/tests/tsan.supp TESSERA_BIN=build/tsan/bin/tessera \
	  build/tsan/bin/run-tests --filter service_finished_image_is_saved_off_the_loop
	TSAN_OPTIONS=suppressions=$(CURDIR)/tests/tsan.supp TESSERA_BIN=build/tsan/bin/tessera \
	  build/tsan/bin/run-tests --filter adaptive_rounds_share_one_loaded_scene_on_a_worker
	TSAN_OPTIONS=suppressions=$(CURDIR)/tests/tsan.supp TESSERA_BIN=build/tsan/bin/tessera \
	  build/tsan/bin/run-tests --filter local_fork_

# References: 256x256, cached under bench/ref/ by scene contents.
BENCH_REF_BOX := 8192
BENCH_REF_SPHERES := 4096
bench-reference: $(TESSERA) $(WORKER)
	bench/reference.sh $(TESSERA) scenes/cornell-box.json 256 $(BENCH_REF_BOX)
	bench/reference.sh $(TESSERA) scenes/cornell-spheres.json 256 $(BENCH_REF_SPHERES)

bench: $(TESSERA) $(WORKER) $(LOADGEN) bench-reference
	bench/bench.sh $(TESSERA) scenes/cornell-box.json 16
	bench/bench.sh $(TESSERA) scenes/cornell-spheres.json 16
	bench/farm.sh $(BUILD)/bin scenes/cornell-box.json 8 5
	bench/features.sh $(TESSERA) 5
	bench/accel.sh $(TESSERA) 3
	bench/error.sh $(TESSERA) scenes/cornell-box.json $(BENCH_REF_BOX) "4 16 64 256" "0.1 0.05" 256 quick

bench-full: $(TESSERA) $(WORKER) bench-reference
	bench/error.sh $(TESSERA) scenes/cornell-box.json $(BENCH_REF_BOX) "4 16 64 256 1024" \
	  "0.1 0.05 0.025 0.0125 0.00625" 1024
	bench/error.sh $(TESSERA) scenes/cornell-spheres.json $(BENCH_REF_SPHERES) "4 16 64 256 1024" \
	  "0.1 0.05 0.025 0.0125" 1024

reference: $(TESSERA)
	@mkdir -p tests/data
	$(TESSERA) render tests/scenes/cornell-small.json --spp 16384 --seed 999 --workers 0 -o tests/data/cornell-ref-64.pfm
	gzip -9 -f tests/data/cornell-ref-64.pfm

clean:
	rm -rf build out

# libFuzzer targets (clang), under ASan + UBSan: `make fuzz FUZZ_SECONDS=N`
# runs each for N seconds from the seeds in tests/fuzz/corpus/TARGET; new
# inputs and any crash go to build/fuzz/ (a crash fails the target).
FUZZ_TARGETS := scene obj frames image
FUZZ_SECONDS ?= 20
FUZZ_BUILD := build/fuzz
FUZZ_CFLAGS := $(CFLAGS_COMMON) -O1 -fno-omit-frame-pointer -fsanitize=fuzzer-no-link,address,undefined \
               -fno-sanitize-recover=all -I$(FUZZ_BUILD)
FUZZ_COMMON_OBJ := $(COMMON_SRC:%.c=$(FUZZ_BUILD)/%.o)
FUZZ_BINS := $(addprefix $(FUZZ_BUILD)/fuzz_,$(FUZZ_TARGETS))

.PRECIOUS: $(FUZZ_BUILD)/%.o
$(FUZZ_BUILD)/common/net/protocol.o: $(FUZZ_BUILD)/build_id.h
$(FUZZ_BUILD)/%.o: %.c | $(DEPS_STAMP)
	@mkdir -p $(dir $@)
	clang $(FUZZ_CFLAGS) -c $< -o $@

$(FUZZ_BUILD)/fuzz_%: LDLIBS += $(LINKED_AT_START)
$(FUZZ_BUILD)/fuzz_%: tests/fuzz/fuzz_%.c $(FUZZ_COMMON_OBJ)
	clang $(FUZZ_CFLAGS) -fsanitize=fuzzer -o $@ $^ $(LDLIBS)

fuzz: $(FUZZ_BINS)
	@for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_BUILD)/corpus-$$t; \
	  echo "fuzz_$$t: $(FUZZ_SECONDS) s"; \
	  $(FUZZ_BUILD)/fuzz_$$t -max_total_time=$(FUZZ_SECONDS) -max_len=65536 -timeout=10 -rss_limit_mb=2048 \
	    -print_final_stats=1 -artifact_prefix=$(FUZZ_BUILD)/crash-$$t- \
	    $(FUZZ_BUILD)/corpus-$$t tests/fuzz/corpus/$$t 2>&1 | grep -E "^Done [0-9]+ runs|^stat::peak_rss_mb|ERROR|SUMMARY|Test unit written" ; \
	  [ "$${PIPESTATUS[0]}" -eq 0 ] || { echo "fuzz_$$t found a failure: see $(FUZZ_BUILD)/crash-$$t-*"; exit 1; }; \
	done; echo "fuzz: $(words $(FUZZ_TARGETS)) targets, no failures"

-include $(FUZZ_COMMON_OBJ:.o=.d)
-include $(COMMON_OBJ:.o=.d) $(TEST_OBJ:.o=.d) $(COORD_OBJ:.o=.d) $(CLI_OBJ:.o=.d) $(WORKER_OBJ:.o=.d) $(BUILD)/bench/loadgen.d $(BUILD)/bench/seal_speed.d $(BUILD)/bench/accel_speed.d \
         $(BUILD)/walk_count/bench/accel_speed.d $(BUILD)/walk_count/common/render/accel_wide.d

# ---- make install (issue 18) -------------------------------------------------
# `make install [PREFIX=/usr/local] [DESTDIR=]` copies tessera and tessera-worker
# into $(DESTDIR)$(PREFIX)/bin and links tessera-coordinator to tessera there
# (tessera finds tessera-worker next to itself). INSTALL_FROM=DIR installs
# binaries already built elsewhere without building (tests/test_install.c).
PREFIX ?= /usr/local
INSTALL_FROM ?= $(BUILD)/bin
.PHONY: install uninstall
install: $(if $(filter $(BUILD)/bin,$(INSTALL_FROM)),$(TESSERA) $(WORKER))
	install -d "$(DESTDIR)$(PREFIX)/bin"
	install -m 755 "$(INSTALL_FROM)/tessera" "$(INSTALL_FROM)/tessera-worker" "$(DESTDIR)$(PREFIX)/bin/"
	ln -sf tessera "$(DESTDIR)$(PREFIX)/bin/tessera-coordinator"
uninstall:
	rm -f "$(DESTDIR)$(PREFIX)/bin/tessera" "$(DESTDIR)$(PREFIX)/bin/tessera-worker" \
	      "$(DESTDIR)$(PREFIX)/bin/tessera-coordinator"
# Slurm (docs/slurm.md): the batch scripts in docker/slurm/ against a real,
# private one-node cluster under build/slurm/ (tests/slurm/run.sh: needs
# root, installs slurm-wlm and munge when missing, stops exactly the daemons
# it started; prints "slurm-test: skipped (...)" when it cannot run).
.PHONY: slurm-test slurm-bench
slurm-test: $(TESSERA) $(WORKER)
	tests/slurm/run.sh $(BUILD)/bin
# One worker per node (--threads = its CPUs) against one per Slurm task.
SLURM_BENCH_ROUNDS ?= 3
slurm-bench: $(TESSERA) $(WORKER)
	tests/slurm/run.sh $(BUILD)/bin --bench-layout $(SLURM_BENCH_ROUNDS)
# ---- glTF / OBJ+MTL import (issue 14): Assimp reads the models ------------
DEB_PACKAGES += libassimp-dev
FUZZ_TARGETS += gltf
fuzz: $(FUZZ_BUILD)/fuzz_gltf
# ---- Tessera against Blender Cycles in the same run (issue 15) ----
#   make bench-cycles        both scenes at 64 and 256 spp, median of 3, against Cycles references
#                            (box 8192 spp, spheres 4096; cached in bench/ref/; 5-10 min each idle);
#                            bench/results/cycles-same-run.{csv,md,png}. Also part of make bench.
#   make bench-cycles-depth  variance by path length, Tessera and Cycles (docs/performance.md)
#   make bench-cycles-seeds  the same-run table without a converged reference (two seeds each;
#                            for a busy machine where the big references cannot be made in time)
# Needs Blender (Debian's blender, installed here if missing): a benchmark dependency only.
BENCH_DEB_PACKAGES := blender libsqlite3-dev
BENCH_CYCLES_SCENES := scenes/cornell-box.json scenes/cornell-spheres.json@4096
BENCH_CYCLES_SPP := 64 256
BENCH_CYCLES_REPEATS := 3
.PHONY: bench-cycles bench-cycles-depth bench-cycles-seeds bench-deps
bench-deps:
	@missing=""; for p in $(BENCH_DEB_PACKAGES); do dpkg -s $$p > /dev/null 2>&1 || missing="$$missing $$p"; done; \
	[ -z "$$missing" ] || { SUDO=""; [ "$$(id -u)" -ne 0 ] && SUDO=sudo; \
	  $$SUDO apt-get -o DPkg::Lock::Timeout=900 update -qq && DEBIAN_FRONTEND=noninteractive \
	  $$SUDO apt-get install -y -qq -o DPkg::Lock::Timeout=900 $$missing; }
bench-cycles: $(TESSERA) $(WORKER) bench-deps
	bench/cycles.sh $(TESSERA) "$(BENCH_CYCLES_SCENES)" "$(BENCH_CYCLES_SPP)" $(BENCH_CYCLES_REPEATS)
bench-cycles-depth: $(TESSERA) $(WORKER) bench-deps
	bench/cycles-depth.sh $(TESSERA) "$(BENCH_CYCLES_SCENES)" "1 2 3 4 5 6 7 8" 64
bench-cycles-seeds: $(TESSERA) $(WORKER) bench-deps
	bench/cycles-seeds.sh $(TESSERA) "$(BENCH_CYCLES_SCENES)" "$(BENCH_CYCLES_SPP)"
bench: bench-cycles
# ---- big meshes (issue 13) ----------------------------------------------------
# `make bench-meshes`: cornell-spheres with icosphere meshes of 41k to 2.6M
# triangles and a subdivided Suzanne of 1M, Tessera and Blender Cycles
# interleaved in the same run (bench/meshes.sh; MESH_SCENES, MESH_SPP,
# MESH_ROUNDS to change; "9" adds 10.5M triangles), also Tessera with
# Cycles' roulette rule (--roulette-depth 1), then each one's noise per
# sample from two more seeds (MESH_ERROR=0 skips them), table printed, CSV
# and plot in bench/results/meshes.{csv,png}.
MESH_SCENES ?= 5 6 7 8 suzanne5
MESH_SPP ?= 64
MESH_ROUNDS ?= 1
.PHONY: bench-meshes
bench-meshes: $(TESSERA) $(WORKER) bench-deps
	bench/meshes.sh $(BUILD)/bin "$(MESH_SCENES)" $(MESH_SPP) $(MESH_ROUNDS)
# ---- Containers (issue 12; docs/containers.md) ----
#   make docker       build tessera:latest (first the debian:12 base images with
#                     debootstrap when the engine has none; docker/token when missing)
#   make docker-test  the container tests against the real engine (Compose, faults,
#                     Swarm); ends with "N passed, N failed"
.PHONY: docker docker-test
docker:
	GIT_ID=$(GIT_ID) docker/build.sh

docker-test: docker $(TESSERA) $(WORKER)
	GIT_ID=$(GIT_ID) tests/docker/run.sh

# ---- web dashboard (issue 16; coordinator/http.c, dashboard.c) ----
# libhttp-parser parses the requests (DEB_PACKAGES: libhttp-parser-dev,
# LDLIBS: -lhttp_parser). The fuzz target drives the request parser, which
# lives with the coordinator, not in common/.
DEB_PACKAGES += libhttp-parser-dev
LDLIBS += -lhttp_parser
# HTTPS for the dashboard (--http-cert, --http-key; coordinator/tls.c):
# OpenSSL's memory BIOs under the server's own libuv sockets. The tests make
# their certificates with the openssl command and fetch with curl.
DEB_PACKAGES += libssl-dev openssl curl
LDLIBS += -lssl -lcrypto
FUZZ_TARGETS += http
# The browser test (headless Chromium screenshot) and the Prometheus parser
# check run when these are present and print a skip line otherwise.
DEB_PACKAGES += chromium python3-prometheus-client
fuzz: $(FUZZ_BUILD)/fuzz_http
$(FUZZ_BUILD)/fuzz_http: tests/fuzz/fuzz_http.c $(FUZZ_BUILD)/coordinator/http.o $(FUZZ_BUILD)/coordinator/connlimit.o \
                         $(FUZZ_BUILD)/coordinator/tls.o \
                         $(FUZZ_COMMON_OBJ)
	clang $(FUZZ_CFLAGS) -fsanitize=fuzzer -o $@ $^ $(LDLIBS)

# ---- Reliability (issue 20, issue 18 item 3) --------------------------------
# bench-journal: tiles/s of the load test through the job service with its
# tile journal on (bench/journal.sh ROUNDS CONNECTIONS; README "Reliability").
.PHONY: bench-journal
bench-journal: $(TESSERA) $(LOADGEN)
	bench/journal.sh 3 100

# bench-upload-stall: the loop's longest iteration and the slowest status
# while the largest scene the coordinator accepts uploads (README "Reliability").
.PHONY: bench-upload-stall
bench-upload-stall: $(TESSERA) $(WORKER)
	BIN=$(BUILD)/bin bench/upload_stall.py 3

# ---- issue 17: trust on hostile networks --------------------------------------
# Render CPU per intersector, interleaved in one process (docs/meshes.md):
#   build/release/bin/accel-speed SCENE.json --width 128 --height 128 --spp 16 embree wide
ACCEL_SPEED := $(BUILD)/bin/accel-speed
$(ACCEL_SPEED): $(BUILD)/bench/accel_speed.o $(foreach l,render image net base,$(call layer_lib,$(l)))
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)
# `make walk-count`: accel-speed that also counts the wide BVH's walks,
# node tests and leaf tests (its own accel_wide.o, compiled with
# -DTESSERA_WALK_COUNT, linked before the library's): compare two trees by
# counts, which have no noise (docs/meshes.md, thirtieth session).
WALK_COUNT := $(BUILD)/bin/walk-count
$(BUILD)/walk_count/%.o: %.c | $(DEPS_STAMP)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -O3 -DTESSERA_WALK_COUNT -c $< -o $@
$(WALK_COUNT): $(BUILD)/walk_count/bench/accel_speed.o $(BUILD)/walk_count/common/render/accel_wide.o \
               $(foreach l,render image net base,$(call layer_lib,$(l)))
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)
.PHONY: walk-count
walk-count: $(WALK_COUNT)

# What sealed links and audited tiles cost: five configurations of the local
# farm run interleaved (bench/trust.sh; printed, not asserted).
.PHONY: bench-trust
TRUST_BENCH_ROUNDS ?= 5
SEAL_SPEED := $(BUILD)/bin/seal_speed
$(SEAL_SPEED): $(BUILD)/bench/seal_speed.o $(call layer_lib,net) $(call layer_lib,base)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ $(LDLIBS)
bench-trust: $(TESSERA) $(WORKER) $(LOADGEN) $(SEAL_SPEED)
	$(SEAL_SPEED)
	bench/trust.sh $(BUILD)/bin scenes/cornell-box.json 16 $(TRUST_BENCH_ROUNDS) 32

# ---- issue 20: job store, files or SQLite (docs/jobstore.md) ------------------
# bench-jobstore: job-record operations (create, update, recover/list,
# expire) on the current files and on an SQLite (WAL) prototype; a bench
# only (libsqlite3-dev), not linked into the product.
.PHONY: bench-jobstore
JOBSTORE_BENCH := $(BUILD)/bin/jobstore-bench
$(BUILD)/bench/jobstore.o: | bench-deps
$(JOBSTORE_BENCH): $(BUILD)/bench/jobstore.o $(call layer_lib,base)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -o $@ $^ -lsqlite3 $(LDLIBS)
JOBSTORE_JOBS ?= 10000
JOBSTORE_DURABLE ?= 1000
bench-jobstore: $(JOBSTORE_BENCH)
	d=$$(mktemp -d $${TMPDIR:-/tmp}/tessera-jobstore.XXXXXX) && $(JOBSTORE_BENCH) $$d $(JOBSTORE_JOBS) $(JOBSTORE_DURABLE); rc=$$?; rm -rf $$d; exit $$rc

# ---- issue 20: leaks fail the ASan run; the soak ---------------------------
# test-lsan: the load test (loadgen), worker churn and every client request
# against the ASan build with LeakSanitizer on (tests/lsan.sh); part of
# test-asan, which also runs every test with detect_leaks=1 and each
# process's report written to build/asan/reports/ (log_path), so a leak in
# any coordinator, worker or client a test starts fails the run whatever
# the test checks of it.
# soak: bench/soak.sh for SOAK_SECONDS (minutes; not in CI).
.PHONY: test-lsan soak
ASAN_REPORTS := build/asan/reports
LSAN_SECONDS ?= 10
test-lsan:
	$(MAKE) VARIANT=asan all build/asan/bin/loadgen
	tests/lsan.sh build/asan/bin $(LSAN_SECONDS)
SOAK_SECONDS ?= 300
soak: $(TESSERA) $(WORKER) $(LOADGEN)
	bench/soak.sh $(BUILD)/bin $(SOAK_SECONDS)
# The sealed frame layer and the handshake's check (tests/fuzz/fuzz_seal.c).
FUZZ_TARGETS += seal
fuzz: $(FUZZ_BUILD)/fuzz_seal
# An honest farm is never flagged by the audit, over many jobs (make test
# runs 8; docs/audit.md).
.PHONY: bench-audit-soak
AUDIT_SOAK_JOBS ?= 100
bench-audit-soak: $(TESSERA) $(WORKER)
	bench/audit_soak.sh $(BUILD)/bin $(AUDIT_SOAK_JOBS)
