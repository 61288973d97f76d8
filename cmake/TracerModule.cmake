# tracer_module(<target> <folder>): an include root for <target> that exposes <folder> alone.
# The root is <build>/include/<name>, holding one link <name> -> <folder>, so that sources keep
# spelling includes "<name>/file.h". The target puts its root on its PUBLIC (INTERFACE) include
# path and inherits its dependencies' roots through target_link_libraries; no root holds the
# source tree itself. A header of a module that a target does not link is then not found: an
# upward include fails to build (tests/layers.cmake checks that it does).
function(tracer_module target folder)
  get_filename_component(name ${folder} NAME)
  set(root ${PROJECT_BINARY_DIR}/include/${name})
  file(MAKE_DIRECTORY ${root})
  file(CREATE_LINK ${folder} ${root}/${name} SYMBOLIC)
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    target_include_directories(${target} INTERFACE ${root})
  else()
    target_include_directories(${target} PUBLIC ${root})
  endif()
endfunction()
