# Install rules (GNUInstallDirs) and the Debian package of the rig host (CPack DEB):
#   cmake --install build/X --prefix /usr      the programs, the unit, /etc/leveler/rig.ini, docs
#   cpack -G DEB --config build/X/CPackConfig.cmake
# The unit in boards/linux-rig names /usr/local (a hand install, its header says
# how); the installed copy names where this install puts the programs and docs.
# The rig host's layout is Debian's: programs in /usr/bin, the config in
# /etc/leveler (absolute: the unit names it), the unit under lib/systemd. The
# prefix defaults to /usr so that the unit installed with `cmake --install`
# names the same paths as the package's; the unit is written at install time
# for the prefix of that install (cmake/install_unit.cmake).
if(CMAKE_INSTALL_PREFIX_INITIALIZED_TO_DEFAULT)
  set(CMAKE_INSTALL_PREFIX /usr CACHE PATH "install prefix" FORCE)
endif()
include(GNUInstallDirs)
set(LEVELER_ETC_DIR /etc/leveler)

set(LEVELER_PROGRAMS leveler-rig leveler-mbaps leveler-plant-server leveler-schedule-run leveler-sim)
foreach(prog IN LISTS LEVELER_PROGRAMS)
  if(TARGET ${prog})
    install(TARGETS ${prog} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT rig)
  endif()
endforeach()

set(RIG_DIR ${PROJECT_SOURCE_DIR}/boards/linux-rig)
install(CODE "set(LEVELER_UNIT_SOURCE \"${RIG_DIR}/leveler-rig.service\")
set(LEVELER_UNIT_BINDIR \"${CMAKE_INSTALL_BINDIR}\")
set(LEVELER_UNIT_DOCDIR \"${CMAKE_INSTALL_DOCDIR}\")" COMPONENT rig)
# the unit and the udev rule under <prefix>/lib (/usr/lib on Debian 12, merged /usr)
install(SCRIPT ${CMAKE_CURRENT_LIST_DIR}/install_unit.cmake COMPONENT rig)
install(FILES ${RIG_DIR}/60-leveler-gpio.rules DESTINATION lib/udev/rules.d COMPONENT rig)
install(FILES ${RIG_DIR}/rig.ini DESTINATION ${LEVELER_ETC_DIR} COMPONENT rig)
install(FILES ${RIG_DIR}/README.md ${RIG_DIR}/stunnel-modbus-security.conf
        DESTINATION ${CMAKE_INSTALL_DOCDIR}/linux-rig COMPONENT rig)
install(FILES ${LEVELER_REGMAP_TAGS} DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT rig)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT rig
        FILES_MATCHING PATTERN "*.md")
install(DIRECTORY ${PROJECT_SOURCE_DIR}/host_sim/configs/ DESTINATION ${CMAKE_INSTALL_DATADIR}/leveler/configs
        COMPONENT rig FILES_MATCHING PATTERN "*.ini")

set(CPACK_PACKAGE_NAME leveler-rig)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "leveler maintainers <leveler@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "air-spring leveling controller: the firmware on a Linux rig host")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr) # a Debian package, whatever this build's own prefix
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_COMPRESSION_TYPE gzip) # fast to build in a test; the package is small
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF) # a sanitized test build links libasan; dpkg-shlibdeps is not needed to test
set(CPACK_DEBIAN_PACKAGE_DEPENDS "libmodbus5, libgpiod2 | libgpiod3, libinih1, libcjson1, libsystemd0, libssl3")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${RIG_DIR}/debian/conffiles ${RIG_DIR}/debian/postinst ${RIG_DIR}/debian/prerm ${RIG_DIR}/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
