# lode_add_plugin(NAME <kind.name> SOURCES <files...> [TESTS <files...>] [LIBS <targets...>]
#                 [TEST_LIBS <targets...>])
#
# Builds:
#   lode_<id>_obj   object library with the plugin's code (tests link it to reach internals)
#   lode-<NAME>.so  the loadable module in ${LODE_BUILD_PLUGIN_DIR}, installed next to the
#                   other plugins
#   <id>_test       one GoogleTest executable from TESTS, registered with ctest; LIBS link to
#                   the plugin and its test, TEST_LIBS (test helpers) to the test only
function(lode_add_plugin)
  cmake_parse_arguments(P "" "NAME" "SOURCES;TESTS;LIBS;TEST_LIBS" ${ARGN})
  if(NOT P_NAME OR NOT P_SOURCES)
    message(FATAL_ERROR "lode_add_plugin: NAME and SOURCES are required")
  endif()
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

# lode_add_plugin_library(NAME <name> SOURCES <files...> [LIBS <targets...>])
#
# Builds lode_<name>, the static (PIC) library of what a family's plugins share, from
# plugins/<kind>/common; its folder is on the include path of every target that links it
# (through lode_add_plugin's LIBS).
function(lode_add_plugin_library)
  cmake_parse_arguments(L "" "NAME" "SOURCES;LIBS" ${ARGN})
  add_library(lode_${L_NAME} STATIC ${L_SOURCES})
  set_target_properties(lode_${L_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  target_link_libraries(lode_${L_NAME} PUBLIC lodestone::core Eigen3::Eigen ${L_LIBS})
  target_include_directories(lode_${L_NAME} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR})
  lode_set_warnings(lode_${L_NAME})
endfunction()
