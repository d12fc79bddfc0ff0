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
#   <id>_test       one GoogleTest executable from TESTS, registered with ctest
function(lode_add_plugin)
  cmake_parse_arguments(P "" "NAME" "SOURCES;TESTS;LIBS;TEST_LIBS" ${ARGN})
  if(NOT P_NAME OR NOT P_SOURCES)
    message(FATAL_ERROR "lode_add_plugin: NAME and SOURCES are required")
  endif()
  lode_add_family_common()
  string(REPLACE "." "_" id ${P_NAME})
  add_library(lode_${id}_obj OBJECT ${P_SOURCES})
  target_link_libraries(lode_${id}_obj PUBLIC lodestone::core Eigen3::Eigen ${P_LIBS})
  target_include_directories(lode_${id}_obj PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
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

# The shared code of the calling plugin's family (plugins/<kind>/common), when a partial build
# (LODE_PLUGINS) leaves that folder out: the plugins of the family still link it. A complete
# build adds it with the other folders of plugins/.
function(lode_add_family_common)
  get_filename_component(family_dir ${CMAKE_CURRENT_SOURCE_DIR} DIRECTORY)
  get_filename_component(family ${family_dir} NAME)
  get_property(added GLOBAL PROPERTY lode_family_common_${family})
  if(added OR NOT LODE_PLUGINS OR NOT EXISTS ${family_dir}/common/CMakeLists.txt
     OR "${family}/common" MATCHES "^(${LODE_PLUGINS})$")
    return()
  endif()
  set_property(GLOBAL PROPERTY lode_family_common_${family} TRUE)
  add_subdirectory(${family_dir}/common ${CMAKE_BINARY_DIR}/plugins/${family}/common)
endfunction()
