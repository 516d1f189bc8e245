# The compiled parts of the leveler Python package, for pip install .
# (pyproject.toml: scikit-build-core builds the targets named there and
# installs the component "python" into the wheel's platlib):
#   leveler/_lib/   libleveler_diag.so (the engine: the C plant for the diagnosis, the
#                   config loader and the PIL harness), libleveler_truth.so (the blind test's truths)
#   leveler/_bin/   leveler-sim (the one config loader: leveler-sim --dump-config)
#   leveler/_data/  the simulator configs, the effect and truth catalogues, the
#                   register map (registers.json: the mode register's values), the sweep studies
# scripts/leveler/paths.py finds them there. No sanitizers, no tests, no rig
# host (libmodbus, libgpiod), no CPack, no firmware cross build.
#
# An editable install (pip install -e ., scripts/bootstrap) installs nothing
# compiled: the checkout's build folders serve it as before, and a library
# rebuilt there is never shadowed by a stale copy in site-packages.
if(SKBUILD_STATE STREQUAL "editable")
  message(STATUS "leveler: editable install; the compiled parts come from the checkout's build folders")
  return()
endif()
if(LEVELER_SANITIZE OR LEVELER_COVERAGE OR LEVELER_FUZZ)
  message(FATAL_ERROR "LEVELER_PYTHON_PACKAGE: the wheel is built without sanitizers, coverage or fuzzing")
endif()

add_subdirectory(firmware)
add_subdirectory(host_sim)

set(LEVELER_PY_TARGETS leveler_diag leveler_truth leveler-sim)
foreach(t IN LISTS LEVELER_PY_TARGETS)
  if(NOT TARGET ${t})
    message(FATAL_ERROR "LEVELER_PYTHON_PACKAGE: target ${t} is not configured (see the messages above)")
  endif()
endforeach()
install(TARGETS leveler_diag leveler_truth LIBRARY DESTINATION leveler/_lib COMPONENT python)
install(TARGETS leveler-sim RUNTIME DESTINATION leveler/_bin COMPONENT python)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/host_sim/configs/ DESTINATION leveler/_data/configs
        COMPONENT python FILES_MATCHING PATTERN "*.ini")
# leveler-sweep's studies (--study NAME); their "../configs/..." paths land on the configs above
install(DIRECTORY ${PROJECT_SOURCE_DIR}/host_sim/studies/ DESTINATION leveler/_data/studies
        COMPONENT python FILES_MATCHING PATTERN "*.toml")
install(FILES ${PROJECT_SOURCE_DIR}/host_sim/plant/effects.json ${PROJECT_SOURCE_DIR}/firmware/regmap/registers.json
        DESTINATION leveler/_data COMPONENT python)
install(FILES ${PROJECT_SOURCE_DIR}/host_sim/blindtest/truth.json ${PROJECT_SOURCE_DIR}/host_sim/blindtest/truth2.json
        DESTINATION leveler/_data/blindtest COMPONENT python)
