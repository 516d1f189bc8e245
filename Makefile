# Thin wrapper over CMake. Each target builds in its own folder under build/.
#   make test       unit, simulator, Modbus and analysis tests (ASan+UBSan host build) + board build checks
#   make sim        the 900 lb thesis case with the firmware in the loop -> build/sim/
#   make firmware   STM32F103 image -> build/stm32f103/leveler.{elf,bin,hex} + size report
#   make pil        that image emulated (Qiling) against the plant: 900 lb case beside leveler-sim
#   make bench      speed figures (simulator, diagnosis, PIL cases and tick cost) and the controller scorecard (docs/controller.md)
#   make coverage   line coverage of firmware/ (gcovr)
#   make fuzz       libFuzzer on the Modbus RTU frame parser (FUZZ_SECONDS=60)
#   make soak       the rig's 10-minute chaos soak (CTest label soak; a 60 s one runs in make test)
#   make blindtest  the full blind test of the sim-to-real diagnosis
#   make flash      write build/stm32f103/leveler.bin to the board (OpenOCD or st-flash)
#   make package    the rig host's Debian package -> build/package/leveler-rig_<version>_<arch>.deb
#   make clean

JOBS      ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE     ?= cmake
PY        := $(CURDIR)/.venv/bin/python
FUZZ_SECONDS ?= 60
export LEVELER_PYTHON := $(PY)

.PHONY: all test sim pil firmware bench coverage fuzz soak blindtest flash clean bootstrap

all: test

bootstrap:
	@scripts/bootstrap

# configure(dir, extra cmake args)
define configure
	@$(CMAKE) -S . -B $(1) -DLEVELER_PYTHON=$(PY) $(2) > $(1).configure.log 2>&1 || (cat $(1).configure.log; exit 1)
endef

test: bootstrap firmware
	@mkdir -p build
	$(call configure,build/test,-DCMAKE_BUILD_TYPE=Debug -DLEVELER_SANITIZE=ON)
	$(CMAKE) --build build/test -j $(JOBS)
	cd build/test && ctest --output-on-failure -j $(JOBS) -LE '^soak$$'

sim: bootstrap
	@mkdir -p build
	$(call configure,build/sim,-DCMAKE_BUILD_TYPE=Release)
	$(CMAKE) --build build/sim -j $(JOBS)
	$(CMAKE) --build build/sim --target run-thesis-sim

firmware: bootstrap
	@mkdir -p build
	$(call configure,build/stm32f103,-DCMAKE_BUILD_TYPE=MinSizeRel -DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/cmake/arm-none-eabi.cmake)
	$(CMAKE) --build build/stm32f103 -j $(JOBS)

# make pil [PIL_CONFIG=my-rig-model.ini]: the image under emulation on that config (default the thesis 900 lb)
pil: bootstrap firmware
	@mkdir -p build
	$(call configure,build/pil,-DCMAKE_BUILD_TYPE=Release -DLEVELER_PIL_CONFIG=$(abspath $(or $(PIL_CONFIG),host_sim/configs/thesis-900lb.ini)))
	$(CMAKE) --build build/pil -j $(JOBS)
	$(CMAKE) --build build/pil --target run-pil

package: bootstrap
	@mkdir -p build
	$(call configure,build/package,-DCMAKE_BUILD_TYPE=Release)
	$(CMAKE) --build build/package -j $(JOBS)
	cd build/package && cpack -G DEB

flash: firmware
	$(CMAKE) --build build/stm32f103 --target flash

bench: bootstrap firmware
	@mkdir -p build
	$(call configure,build/bench,-DCMAKE_BUILD_TYPE=Release)
	$(CMAKE) --build build/bench -j $(JOBS)
	$(CMAKE) --build build/bench --target run-bench

coverage: bootstrap
	@mkdir -p build
	$(call configure,build/coverage,-DCMAKE_BUILD_TYPE=Debug -DLEVELER_COVERAGE=ON)
	$(CMAKE) --build build/coverage -j $(JOBS)
	cd build/coverage && ctest -L unit -j $(JOBS) --output-on-failure
	$(CMAKE) --build build/coverage --target coverage-report

fuzz: bootstrap
	@mkdir -p build
	$(call configure,build/fuzz,-DCMAKE_BUILD_TYPE=Debug -DCMAKE_C_COMPILER=clang -DLEVELER_FUZZ=ON)
	$(CMAKE) --build build/fuzz -j $(JOBS)
	$(CMAKE) --build build/fuzz --target run-fuzz -- FUZZ_SECONDS=$(FUZZ_SECONDS)

soak: bootstrap
	@mkdir -p build
	$(call configure,build/test,-DCMAKE_BUILD_TYPE=Debug -DLEVELER_SANITIZE=ON)
	$(CMAKE) --build build/test -j $(JOBS)
	cd build/test && ctest --output-on-failure -L '^soak$$'

blindtest: bootstrap
	@mkdir -p build
	$(call configure,build/sim,-DCMAKE_BUILD_TYPE=Release)
	$(CMAKE) --build build/sim -j $(JOBS)
	$(CMAKE) --build build/sim --target run-blindtest

clean:
	rm -rf build
