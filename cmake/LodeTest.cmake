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
