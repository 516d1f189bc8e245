# Run at install time (install(SCRIPT) from cmake/package.cmake): writes the
# systemd unit with the paths of THIS install (cmake --install --prefix P, or
# CPack's /usr), not those of the configure step. The unit in boards/linux-rig
# names /usr/local (a hand install, its header says how).
file(READ "${LEVELER_UNIT_SOURCE}" unit)
string(REGEX REPLACE "^# systemd unit for leveler-rig. Install:\n(#   [^\n]*\n)*"
       "# systemd unit for leveler-rig, installed by cmake --install or the leveler-rig package.\n" unit "${unit}")
string(REPLACE "/usr/local/bin/" "${CMAKE_INSTALL_PREFIX}/${LEVELER_UNIT_BINDIR}/" unit "${unit}")
string(REPLACE "/usr/local/share/doc/leveler/" "${CMAKE_INSTALL_PREFIX}/${LEVELER_UNIT_DOCDIR}/" unit "${unit}")
set(dest "$ENV{DESTDIR}${CMAKE_INSTALL_PREFIX}/lib/systemd/system")
file(MAKE_DIRECTORY "${dest}")
file(WRITE "${dest}/leveler-rig.service" "${unit}")
message(STATUS "Installing: ${dest}/leveler-rig.service")
