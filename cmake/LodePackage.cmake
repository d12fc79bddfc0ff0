# Debian packages of lodestone: `cpack -G DEB` in the build folder, or the `package` target.
#
#   lodestone          lode, the board emulators, the core libraries, every plugin, the example
#                      pipelines (/usr/share/lodestone/config), the lode@ unit, the udev rule,
#                      the limits file, /etc/lodestone, man pages and bash completion
#   lodestone-dev      the SDK and runtime headers, the CMake package (find_package(lodestone),
#                      LodePluginExternal.cmake), the telemetry IDL, the HAL's static library
#   *-dbgsym (.ddeb)   the debug symbols split off the stripped binaries
#
# Install components (the top CMakeLists.txt makes `runtime` the default):
#   runtime                          -> lodestone
#   system (absolute /etc and /lib)  -> lodestone; EXCLUDE_FROM_ALL, so `cmake --install
#                                       --prefix DIR` never writes into the build host's /etc
#   cmake_package, sdk, runtime_headers -> lodestone-dev
# cpack installs each component into its own staging tree with DESTDIR (CPACK_SET_DESTDIR),
# which is what lets the system component's absolute paths land inside the package.

set(LODE_PACKAGE_MAINTAINER "lodestone maintainers <lodestone@example.org>"
  CACHE STRING "Maintainer field (and changelog signature) of the Debian packages")
set(LODE_PACKAGE_RELEASE 1 CACHE STRING "Debian revision of the packages (VERSION-RELEASE)")
set(LODE_DEB_VERSION ${PROJECT_VERSION}-${LODE_PACKAGE_RELEASE})
set(lode_deploy ${PROJECT_SOURCE_DIR}/apps/deploy)

# --- what only the packages carry: the host's integration -------------------------------
install(FILES ${lode_deploy}/lode@.service DESTINATION /lib/systemd/system
  COMPONENT system EXCLUDE_FROM_ALL)
install(FILES ${lode_deploy}/60-lodestone.rules DESTINATION /lib/udev/rules.d
  COMPONENT system EXCLUDE_FROM_ALL)
install(FILES ${lode_deploy}/limits.conf DESTINATION /etc/security/limits.d RENAME lodestone.conf
  COMPONENT system EXCLUDE_FROM_ALL)
install(DIRECTORY DESTINATION /etc/lodestone COMPONENT system EXCLUDE_FROM_ALL)  # lode@NAME reads NAME.yaml
set(lode_conffiles /etc/security/limits.d/lodestone.conf)

# --- the example pipelines: self-contained YAML, run from any folder ----------------------
install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/lodestone/config
  COMPONENT runtime FILES_MATCHING PATTERN "*.yaml")

# --- /usr/share/doc/<package>: copyright and changelog.Debian.gz (gzip -9n: no timestamp) --
# The changelog is dated by the commit it is built from, so two builds of one commit match.
execute_process(COMMAND git log -1 --format=%cD
  WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} OUTPUT_VARIABLE LODE_CHANGELOG_DATE
  OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET RESULT_VARIABLE lode_git_result)
if(NOT lode_git_result EQUAL 0 OR NOT LODE_CHANGELOG_DATE)
  string(TIMESTAMP LODE_CHANGELOG_DATE "%a, %d %b %Y %H:%M:%S +0000" UTC)
endif()
set(lode_pkg_dir ${PROJECT_BINARY_DIR}/package)
configure_file(${lode_deploy}/changelog.in ${lode_pkg_dir}/changelog.Debian @ONLY)
add_custom_command(OUTPUT ${lode_pkg_dir}/changelog.Debian.gz
  COMMAND gzip -9nf -k ${lode_pkg_dir}/changelog.Debian
  DEPENDS ${lode_pkg_dir}/changelog.Debian
  COMMENT "Debian changelog" VERBATIM)
add_custom_target(lode_deb_changelog ALL DEPENDS ${lode_pkg_dir}/changelog.Debian.gz)
foreach(lode_pkg_component IN ITEMS runtime cmake_package)
  if(lode_pkg_component STREQUAL runtime)
    set(lode_doc_dir ${CMAKE_INSTALL_DATADIR}/doc/lodestone)
  else()
    set(lode_doc_dir ${CMAKE_INSTALL_DATADIR}/doc/lodestone-dev)
  endif()
  install(FILES ${lode_deploy}/copyright ${lode_pkg_dir}/changelog.Debian.gz
    DESTINATION ${lode_doc_dir} COMPONENT ${lode_pkg_component})
endforeach()

# --- maintainer scripts and conffiles -----------------------------------------------------
string(REPLACE ";" "\n" lode_conffiles_text "${lode_conffiles}")
file(WRITE ${lode_pkg_dir}/conffiles "${lode_conffiles_text}\n")
# cpack copies the control files with their own mode: 0755 for scripts, 0644 for conffiles
# (CONTROL_STRICT_PERMISSION), as dpkg and lintian want.
file(COPY ${lode_deploy}/postinst ${lode_deploy}/postrm DESTINATION ${lode_pkg_dir})
# The core libraries are in /usr/lib: dpkg runs ldconfig once after the packages' files are in.
file(WRITE ${lode_pkg_dir}/triggers "activate-noawait ldconfig\n")

# --- CPack -----------------------------------------------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME lodestone)
set(CPACK_PACKAGE_VENDOR "lodestone")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "${LODE_PACKAGE_MAINTAINER}")
# With DESTDIR the install runs with CMAKE_INSTALL_PREFIX = CPACK_INSTALL_PREFIX.
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_SET_DESTDIR ON)
set(CPACK_PACKAGE_DIRECTORY ${PROJECT_BINARY_DIR}/packages CACHE PATH "Where cpack writes the .deb files")
set(CPACK_COMPONENTS_ALL runtime system cmake_package sdk runtime_headers)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_GROUPING ONE_PER_GROUP)

set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE ${LODE_PACKAGE_RELEASE})
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${LODE_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_COMPRESSION_TYPE xz)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The plugins and programs need the core libraries of the same package: look there too.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS usr/${CMAKE_INSTALL_LIBDIR})
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS_POLICY "=")  # no ABI promise across releases yet
# The packaged binaries are stripped either way. With the dbgsym packages (the default) the
# DEB generator does it itself: it copies each ELF file's debug information into the .ddeb
# (objcopy --only-keep-debug, by build id) and then strips the file and links it to that
# copy. CPACK_STRIP_FILES would strip first and leave nothing to split, so it is only the
# way without dbgsym packages.
option(LODE_PACKAGE_DBGSYM "Split the debug symbols into -dbgsym packages (.ddeb)" ON)
if(LODE_PACKAGE_DBGSYM)
  set(CPACK_DEBIAN_DEBUGINFO_PACKAGE ON)
else()
  set(CPACK_STRIP_FILES ON)
endif()
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)

set(CPACK_DEBIAN_LODESTONE_PACKAGE_NAME lodestone)
set(CPACK_DEBIAN_LODESTONE_PACKAGE_SECTION science)
# adduser: postinst creates the `realtime` group and the `lode` user.
set(CPACK_DEBIAN_LODESTONE_PACKAGE_DEPENDS "adduser")
set(CPACK_DEBIAN_LODESTONE_PACKAGE_CONTROL_EXTRA
  ${lode_pkg_dir}/postinst ${lode_pkg_dir}/postrm ${lode_pkg_dir}/conffiles ${lode_pkg_dir}/triggers)
# First line: the synopsis; CPack indents the rest, an empty line separates paragraphs.
set(CPACK_DEBIAN_LODESTONE_DESCRIPTION
"real-time plugin framework for precision motion control
lodestone loads shared-object plugins (boards, plants, sensor models,
estimators, filters, controllers), wires them from a YAML pipeline, checks
it before anything starts and runs the cycle on a real-time thread or on a
simulated clock.

This package holds the lode program, the VME and CAN board emulators, the
core libraries, every plugin, example pipelines, and the lode@ systemd unit
with the udev rule and limits that let the realtime group run pipelines
without root.")

set(CPACK_DEBIAN_DEVEL_PACKAGE_NAME lodestone-dev)
set(CPACK_DEBIAN_DEVEL_PACKAGE_SECTION libdevel)
# The headers include Eigen (and the SDK's test checks GoogleTest); lodestoneConfig.cmake
# finds Eigen3.
set(CPACK_DEBIAN_DEVEL_PACKAGE_DEPENDS "lodestone (= ${LODE_DEB_VERSION}), libeigen3-dev (>= 3.4), libgtest-dev")
set(CPACK_DEBIAN_DEVEL_PACKAGE_SUGGESTS "cmake (>= 3.25), g++ (>= 4:12)")
set(CPACK_DEBIAN_DEVEL_DESCRIPTION
"lodestone plugin SDK: headers and CMake package
Everything needed to build a lodestone plugin out of the source tree: the
SDK and runtime headers, find_package(lodestone) with
lode_add_external_plugin(), the telemetry IDL and the HAL's static library.
A plugin installed with it lands where the installed lode finds it.")

include(CPack)
cpack_add_component_group(lodestone)
cpack_add_component_group(devel)
cpack_add_component(runtime GROUP lodestone)
cpack_add_component(system GROUP lodestone)
cpack_add_component(cmake_package GROUP devel)
cpack_add_component(sdk GROUP devel)
cpack_add_component(runtime_headers GROUP devel)
