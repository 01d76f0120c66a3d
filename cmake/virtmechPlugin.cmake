# virtmech_add_plugin(<name> <source>...): a virtmech plugin, a shared library that
# virtmech.load_plugin (or a scenario's `plugins` key) loads at run time and whose
# VIRTMECH_PLUGIN registration adds kinds to the host's registry. The plugin links its own
# copy of the core (the static library), hidden: nothing of it is exported but the two entry
# points, so that it never interposes on the host's symbols nor the host on its.
function(virtmech_add_plugin name)
  add_library(${name} MODULE ${ARGN})
  target_link_libraries(${name} PRIVATE virtmech::virtmech)
  set_target_properties(${name} PROPERTIES CXX_VISIBILITY_PRESET hidden
                                           VISIBILITY_INLINES_HIDDEN ON
                                           POSITION_INDEPENDENT_CODE ON)
  if(NOT APPLE AND NOT WIN32)
    target_link_options(${name} PRIVATE "LINKER:--exclude-libs,ALL")
  endif()
endfunction()
