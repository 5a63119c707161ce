# sonar3d: the two set-up commands (each installs what it needs, builds, then runs).
#   make demo   simulate the default scene end to end
#   make test   build and pass the tests
#   make docs   the documentation site, offline, in $(BUILD)/docs-site (Debian's mkdocs)
BUILD ?= build
JOBS ?= 2
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
SONAR3D = $(BUILD)/bin/sonar3d
DEMO_OUT ?= $(BUILD)/demo

.PHONY: all deps configure build demo test bench clean format fuzz docs

all: build

deps:
	bash scripts/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD) -j$(JOBS)

# The default scene's objects stand on a seabed at z = 0 that the scene leaves out: neither method
# keeps anything more than 3 cm below it (surfaces lying on the seabed reconstruct on both sides of
# it). docs/carving.md, "The pillar and riser outliers".
DEMO_ROI = --roi -3 -2 -0.03 3 14 3

demo: build
	mkdir -p $(DEMO_OUT)
	$(SONAR3D) simulate data/scenes/reference_objects.yaml -o $(DEMO_OUT)/dataset --overwrite
	$(SONAR3D) info $(DEMO_OUT)/dataset
	$(SONAR3D) preview $(DEMO_OUT)/dataset --frame 130 -o $(DEMO_OUT)/sphere_frame.png
	$(SONAR3D) reconstruct $(DEMO_OUT)/dataset --method carve -o $(DEMO_OUT)/carve.ply $(DEMO_ROI)
	$(SONAR3D) reconstruct $(DEMO_OUT)/dataset --method deconv -o $(DEMO_OUT)/deconv.ply $(DEMO_ROI)
	@echo "== space carving (thesis ch. 4) =="
	$(SONAR3D) evaluate $(DEMO_OUT)/carve.ply --truth $(DEMO_OUT)/dataset --json $(DEMO_OUT)/carve_metrics.json
	@echo "== deconvolution (thesis ch. 5) =="
	$(SONAR3D) evaluate $(DEMO_OUT)/deconv.ply --truth $(DEMO_OUT)/dataset --json $(DEMO_OUT)/deconv_metrics.json
	@echo "demo: outputs in $(DEMO_OUT): dataset/, carve.ply, deconv.ply, *_metrics.json, sphere_frame.png"

test: build
	cd $(BUILD) && ctest --output-on-failure -j$(JOBS)

# docs/ as a browsable site (mkdocs.yml), built with --strict: a broken link or a page left out of
# the navigation fails. Written into the build directory only; open $(DOCS_SITE)/index.html.
# docs/reference.md is generated from the parameters' declarations and kept current by
# tests/test_params.cpp.
DOCS_SITE ?= $(BUILD)/docs-site

docs:
	@command -v mkdocs >/dev/null 2>&1 || bash scripts/install-deps.sh
	mkdocs build --strict -f mkdocs.yml -d $(abspath $(DOCS_SITE))
	@echo "docs: open $(abspath $(DOCS_SITE))/index.html"

bench: build
	$(SONAR3D) bench
	$(BUILD)/bench/bench_sim --benchmark_min_time=2

# Fuzzing (docs/fuzzing.md): builds the libFuzzer targets with clang + ASan/UBSan in $(FUZZ_BUILD)
# and runs each for FUZZ_SECONDS on a copy of its seed corpus, one at a time, at low priority.
# Needs the Debian packages clang and libclang-rt-14-dev.
FUZZ_BUILD ?= build-fuzz
FUZZ_SECONDS ?= 60
FUZZ_TARGETS ?= dataset scene sweep ply mesh holoocean_config pickle navcsv geotiff colmap aris rosmsg rosbag catalogue npz
FUZZ_SAN = -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer

fuzz:
	cmake -S . -B $(FUZZ_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	  -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_CXX_FLAGS="$(FUZZ_SAN)" \
	  -DSONAR3D_FUZZ=ON -DSONAR3D_BUILD_TESTS=OFF -DSONAR3D_BUILD_BENCH=OFF -DSONAR3D_BUILD_PYTHON=OFF
	cmake --build $(FUZZ_BUILD) -j$(JOBS) --target fuzz_targets
	@for t in $(FUZZ_TARGETS); do \
	  mkdir -p $(FUZZ_BUILD)/corpus/$$t && cp -n fuzz/corpus/$$t/* $(FUZZ_BUILD)/corpus/$$t/ ; \
	  echo "== fuzz_$$t for $(FUZZ_SECONDS) s"; \
	  ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$(CURDIR)/fuzz/lsan.supp UBSAN_OPTIONS=print_stacktrace=1 nice -n 19 \
	    $(FUZZ_BUILD)/fuzz/fuzz_$$t $(FUZZ_BUILD)/corpus/$$t -max_total_time=$(FUZZ_SECONDS) \
	    -rss_limit_mb=2048 -timeout=30 -max_len=65536 -print_final_stats=1 \
	    -artifact_prefix=$(FUZZ_BUILD)/fuzz_$$t- > $(FUZZ_BUILD)/fuzz_$$t.log 2>&1; rc=$$?; \
	  grep -E "^(Done|stat::)|ERROR|SUMMARY|Test unit written" $(FUZZ_BUILD)/fuzz_$$t.log; \
	  test $$rc -eq 0 || { echo "fuzz_$$t failed: $(FUZZ_BUILD)/fuzz_$$t.log"; exit 1; }; \
	done

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')

clean:
	rm -rf $(BUILD)
