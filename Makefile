# sonar3d: the two set-up commands (each installs what it needs, builds, then runs).
#   make demo   simulate the default scene end to end
#   make test   build and pass the tests
BUILD ?= build
JOBS ?= 2
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
SONAR3D = $(BUILD)/bin/sonar3d
DEMO_OUT ?= $(BUILD)/demo

.PHONY: all deps configure build demo test bench clean format

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

bench: build
	$(SONAR3D) bench
	$(BUILD)/bench/bench_sim --benchmark_min_time=2

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')

clean:
	rm -rf $(BUILD)
