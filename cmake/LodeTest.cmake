# lode_add_test(NAME <name> SOURCES <files...> [LIBS <targets...>] [LABELS <labels...>])
# A GoogleTest executable registered with ctest; every test can find the built plugins
# (LODE_PLUGIN_PATH) and the repository's config/ folder (LODE_SOURCE_DIR).
function(lode_add_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE lodestone::testing ${T_LIBS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_definitions(${T_NAME} PRIVATE
    LODE_SOURCE_DIR="${PROJECT_SOURCE_DIR}" LODE_BINARY_DIR="${PROJECT_BINARY_DIR}")
  lode_set_warnings(${T_NAME})
  # Tests load every plugin: build them first.
  add_dependencies(${T_NAME} lode_all_plugins)
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  gtest_discover_tests(${T_NAME}
    PROPERTIES ENVIRONMENT "LODE_PLUGIN_PATH=${LODE_BUILD_PLUGIN_DIR}" TIMEOUT ${T_TIMEOUT} LABELS "${T_LABELS}"
    DISCOVERY_TIMEOUT 60)
endfunction()

# lode_add_unavailable_test(NAME <name> WHY <what is missing and how to install it>)
# Stands in for a test whose tool is missing on this machine, so the check never silently
# disappears: it fails with WHY when LODE_REQUIRE_TEST_TOOLS is ON (the test set-up installs
# every tool), and is reported as skipped with WHY otherwise.
function(lode_add_unavailable_test)
  cmake_parse_arguments(U "" "NAME;WHY" "" ${ARGN})
  if(LODE_REQUIRE_TEST_TOOLS)
    add_test(NAME ${U_NAME} COMMAND sh -c "echo 'FAIL: ${U_WHY}'; exit 1")
    message(STATUS "${U_NAME}: ${U_WHY}: the test fails until it is installed")
  else()
    add_test(NAME ${U_NAME} COMMAND sh -c "echo 'SKIP: ${U_WHY}'; exit 77")
    set_tests_properties(${U_NAME} PROPERTIES SKIP_RETURN_CODE 77)
    message(WARNING "${U_NAME}: ${U_WHY}: the test is skipped (LODE_REQUIRE_TEST_TOOLS=OFF)")
  endif()
endfunction()

# lode_allow_tool_skip(<test>): a script test that exits 77 when a tool it needs is missing
# is reported as skipped only when LODE_REQUIRE_TEST_TOOLS is OFF; otherwise 77 is a failure.
function(lode_allow_tool_skip test)
  if(NOT LODE_REQUIRE_TEST_TOOLS)
    set_tests_properties(${test} PROPERTIES SKIP_RETURN_CODE 77)
  endif()
endfunction()

# LODE_H5PY_PYTHON: a python3 that imports h5py and numpy, for the tests that read recordings
# as a user does. Debian's python3-h5py is importable by /usr/bin/python3 (a pyenv python3 on
# PATH usually cannot): the first interpreter that imports both. "" when there is none.
if(NOT DEFINED LODE_H5PY_PYTHON)
  set(h5py_python "")
  find_package(Python3 COMPONENTS Interpreter QUIET)
  foreach(candidate IN ITEMS "${Python3_EXECUTABLE}" /usr/bin/python3)
    if(candidate AND NOT h5py_python)
      execute_process(COMMAND ${candidate} -c "import h5py, numpy" RESULT_VARIABLE h5py_missing
        OUTPUT_QUIET ERROR_QUIET)
      if(h5py_missing EQUAL 0)
        set(h5py_python ${candidate})
      endif()
    endif()
  endforeach()
  set(LODE_H5PY_PYTHON "${h5py_python}" CACHE INTERNAL "python3 with h5py and numpy")
endif()
