# lode_add_plugin(NAME <kind.name> SOURCES <files...> [TESTS <files...>] [LIBS <targets...>]
#                 [TEST_LIBS <targets...>])
#
# LIBS are linked by the plugin and its tests (e.g. its family's shared code, built from
# plugins/<kind>/common), TEST_LIBS by its tests alone (test helpers).
#
# Builds:
#   lode_<id>_obj   object library with the plugin's code (tests link it to reach internals)
#   lode-<NAME>.so  the loadable module in ${LODE_BUILD_PLUGIN_DIR}, installed next to the
#                   other plugins
#   <id>_test       one GoogleTest executable from TESTS, registered with ctest; it also links
#                   TEST_LIBS (test helpers a family of plugins shares)
function(lode_add_plugin)
  cmake_parse_arguments(P "" "NAME" "SOURCES;TESTS;LIBS;TEST_LIBS" ${ARGN})
  if(NOT P_NAME OR NOT P_SOURCES)
    message(FATAL_ERROR "lode_add_plugin: NAME and SOURCES are required")
  endif()
  string(REPLACE "." "_" id ${P_NAME})
  add_library(lode_${id}_obj OBJECT ${P_SOURCES})
  target_link_libraries(lode_${id}_obj PUBLIC lodestone::core Eigen3::Eigen ${P_LIBS})
  target_include_directories(lode_${id}_obj PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  # A module's step() may inline and call its own helpers directly (no PLT): nothing interposes them.
  target_compile_options(lode_${id}_obj PRIVATE -fno-semantic-interposition)
  lode_set_warnings(lode_${id}_obj)

  add_library(lode_${id} MODULE $<TARGET_OBJECTS:lode_${id}_obj>)
  target_link_libraries(lode_${id} PRIVATE lode_${id}_obj)
  set_target_properties(lode_${id} PROPERTIES
    PREFIX "" OUTPUT_NAME "lode-${P_NAME}"
    LIBRARY_OUTPUT_DIRECTORY ${LODE_BUILD_PLUGIN_DIR}
    INSTALL_RPATH "$ORIGIN/../..")
  install(TARGETS lode_${id} LIBRARY DESTINATION ${LODE_INSTALL_PLUGIN_DIR})
  add_dependencies(lode_all_plugins lode_${id})

  if(P_TESTS AND LODE_BUILD_TESTS)
    lode_add_test(NAME ${id}_test SOURCES ${P_TESTS} LIBS lode_${id}_obj ${P_LIBS} ${P_TEST_LIBS})
    add_dependencies(${id}_test lode_${id})
  endif()
endfunction()

# lode_add_family_library(NAME <target> SOURCES <files...> [LIBS <targets...>] [TESTING]
#                         [INCLUDE_DIR <dir>])
#
# What one family of plugins shares, in plugins/<kind>/common/: a static library (position-
# independent: it is linked into each plugin's module) whose sources' folder is on the include
# path of whatever links it, e.g. lode_add_plugin(... LIBS <target>). With TESTING: helpers
# that the family's tests share (built with the tests only, on lodestone::testing and
# GoogleTest), linked with lode_add_plugin(... TEST_LIBS <target>). INCLUDE_DIR (relative to
# the folder) puts another folder on the include path instead, for headers kept apart from
# their sources.
function(lode_add_family_library)
  cmake_parse_arguments(L "TESTING" "NAME;INCLUDE_DIR" "SOURCES;LIBS" ${ARGN})
  if(NOT L_NAME OR NOT L_SOURCES)
    message(FATAL_ERROR "lode_add_family_library: NAME and SOURCES are required")
  endif()
  if(L_TESTING AND NOT LODE_BUILD_TESTS)
    return()
  endif()
  list(GET L_SOURCES 0 first_source)
  get_filename_component(source_dir ${first_source} DIRECTORY)
  if(L_INCLUDE_DIR)
    set(source_dir ${L_INCLUDE_DIR})
  endif()
  add_library(${L_NAME} STATIC ${L_SOURCES})
  set_target_properties(${L_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_link_libraries(${L_NAME} PUBLIC lodestone::core Eigen3::Eigen ${L_LIBS})
  if(L_TESTING)
    target_link_libraries(${L_NAME} PUBLIC lodestone::testing GTest::gtest)
  endif()
  target_include_directories(${L_NAME} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/${source_dir})
  lode_set_warnings(${L_NAME})
endfunction()
