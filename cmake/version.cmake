# leveler/version.h from the top-level VERSION file (read by the top-level
# CMakeLists.txt into PROJECT_VERSION), for the firmware, the run-log writer
# and every program's --version: the target leveler_version carries it.
#
# firmware_version (input register 28) is major*10000 + minor*100 + patch in
# one uint16: 0.6.0 reads 600. That holds for minor, patch < 100, major < 6.
if(PROJECT_VERSION_MINOR GREATER 99 OR PROJECT_VERSION_PATCH GREATER 99 OR PROJECT_VERSION_MAJOR GREATER 5)
  message(FATAL_ERROR "VERSION: ${PROJECT_VERSION} does not fit the firmware_version register "
    "(major*10000 + minor*100 + patch <= 65535 needs minor, patch < 100 and major < 6)")
endif()
math(EXPR LEVELER_VERSION_NUMBER
  "${PROJECT_VERSION_MAJOR} * 10000 + ${PROJECT_VERSION_MINOR} * 100 + ${PROJECT_VERSION_PATCH}")
set(LEVELER_VERSION_DIR ${CMAKE_BINARY_DIR}/generated-version)
configure_file(${CMAKE_CURRENT_LIST_DIR}/version.h.in ${LEVELER_VERSION_DIR}/leveler/version.h @ONLY)
add_library(leveler_version INTERFACE)
target_include_directories(leveler_version INTERFACE ${LEVELER_VERSION_DIR})
