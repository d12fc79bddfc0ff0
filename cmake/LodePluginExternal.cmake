# lode_add_external_plugin(NAME <kind.name> SOURCES <files...> [TESTS <files...>] [LIBS <targets...>])
#
# Builds lode-<NAME>.so against an installed lodestone SDK, the way the project builds its
# own plugins:
#   lode_<id>_obj   object library with the plugin's code (its tests link it to reach internals)
#   lode-<NAME>.so  the loadable module; `cmake --install` puts it in
#                   <prefix>/${LODESTONE_PLUGIN_INSTALL_DIR}, where a `lode` installed in the
#                   same prefix finds it without LODE_PLUGIN_PATH. The prefix defaults to the
#                   SDK's own (/usr for the lodestone-dev package, not /usr/local), so a plain
#                   `cmake --install` puts the plugin beside the packaged ones.
#   <id>_test       with TESTS: one GoogleTest executable (link GTest::gtest_main; the
#                   BlockHarness is <lode/sdk/testing/harness.hpp>), registered with ctest and run
#                   with this plugin and the SDK's plugins on LODE_PLUGIN_PATH
if(CMAKE_INSTALL_PREFIX_INITIALIZED_TO_DEFAULT AND DEFINED LODESTONE_PREFIX)
  set(CMAKE_INSTALL_PREFIX "${LODESTONE_PREFIX}" CACHE PATH "Install prefix (the lodestone SDK's)" FORCE)
endif()

function(lode_add_external_plugin)
  cmake_parse_arguments(P "" "NAME" "SOURCES;TESTS;LIBS" ${ARGN})
  if(NOT P_NAME OR NOT P_SOURCES)
    message(FATAL_ERROR "lode_add_external_plugin: NAME and SOURCES are required")
  endif()
  string(REPLACE "." "_" id ${P_NAME})
  add_library(lode_${id}_obj OBJECT ${P_SOURCES})
  target_link_libraries(lode_${id}_obj PUBLIC lodestone::core ${P_LIBS})
  target_compile_features(lode_${id}_obj PUBLIC cxx_std_20)
  target_include_directories(lode_${id}_obj PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  set_target_properties(lode_${id}_obj PROPERTIES POSITION_INDEPENDENT_CODE ON)

  add_library(lode_${id} MODULE $<TARGET_OBJECTS:lode_${id}_obj>)
  target_link_libraries(lode_${id} PRIVATE lode_${id}_obj)
  set_target_properties(lode_${id} PROPERTIES
    PREFIX "" OUTPUT_NAME "lode-${P_NAME}"
    LIBRARY_OUTPUT_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
  install(TARGETS lode_${id} LIBRARY DESTINATION ${LODESTONE_PLUGIN_INSTALL_DIR})

  if(P_TESTS)
    find_package(GTest REQUIRED)
    add_executable(${id}_test ${P_TESTS})
    target_link_libraries(${id}_test PRIVATE lode_${id}_obj GTest::gtest_main)
    add_dependencies(${id}_test lode_${id})
    add_test(NAME ${id}_test COMMAND ${id}_test)
    # The block under test from this build, the models it may ask for from the SDK.
    set_tests_properties(${id}_test PROPERTIES
      ENVIRONMENT "LODE_PLUGIN_PATH=${CMAKE_CURRENT_BINARY_DIR}:${LODESTONE_PLUGIN_DIR}")
  endif()
endfunction()
