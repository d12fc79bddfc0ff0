# lode_add_external_plugin(NAME <kind.name> SOURCES <files...>)
# Builds lode-<NAME>.so against an installed lodestone SDK. Put its folder on
# LODE_PLUGIN_PATH (or install it to LODESTONE_PLUGIN_DIR) and `lode` loads it like the
# plugins shipped with the project.
function(lode_add_external_plugin)
  cmake_parse_arguments(P "" "NAME" "SOURCES" ${ARGN})
  string(REPLACE "." "_" id ${P_NAME})
  add_library(lode_${id} MODULE ${P_SOURCES})
  target_link_libraries(lode_${id} PRIVATE lodestone::core)
  target_compile_features(lode_${id} PRIVATE cxx_std_20)
  set_target_properties(lode_${id} PROPERTIES PREFIX "" OUTPUT_NAME "lode-${P_NAME}")
endfunction()
