# The module arrows, checked against the include paths the build gives each module: for every
# module, a probe that includes one header of each module it may see must compile, and a probe
# that includes a header of any other module must fail with "No such file or directory". The
# probes are object libraries outside `all`, compiled with the include path of the module's own
# sources; the test Layers.UpwardIncludesFailToBuild builds them (check_layers.cmake).
#
# Each entry: module | a header of it | public dependencies | private dependencies. A module's
# sources see its own folder and what its dependencies export: their folders and, recursively,
# their public dependencies' (a private dependency's folder stops at the module that links it).
set(LAYERS
  "core|core/math.h||"
  "materials|materials/material.h|core|"
  "bvh|bvh/bvh.h|core|"
  "camera|camera/camera.h|core|"
  "image|image/image.h|core|"
  "scene|scene/scene.h|materials bvh camera image|"
  "integrator|integrator/renderer.h|scene image|"
  "cpu|cpu/cpu_backend.h|integrator|"
  "cuda|cuda/cuda_renderer.h|integrator|"
  "backends|backends/backend_select.h|cpu integrator|cuda"
  "ui|ui/workbench.h|backends|"
  "app||ui backends|")
set(LAYER_TARGET_ui ui)
set(LAYER_TARGET_app pathtracer)

set(layer_modules "")
foreach(entry ${LAYERS})
  string(REPLACE "|" ";" fields "${entry}")
  list(GET fields 0 m)
  list(GET fields 1 LAYER_HEADER_${m})
  list(GET fields 2 pub)
  list(GET fields 3 priv)
  separate_arguments(LAYER_PUBLIC_${m} UNIX_COMMAND "${pub}")
  separate_arguments(LAYER_PRIVATE_${m} UNIX_COMMAND "${priv}")
  if(m STREQUAL "cuda" AND NOT TRACER_HAS_CUDA)
    continue()
  endif()
  list(APPEND layer_modules ${m})
endforeach()

# The folders that module m exports to what links it: its own and its public dependencies'.
function(layer_exports m out)
  set(result ${m})
  foreach(d ${LAYER_PUBLIC_${m}})
    layer_exports(${d} sub)
    list(APPEND result ${sub})
  endforeach()
  list(REMOVE_DUPLICATES result)
  set(${out} ${result} PARENT_SCOPE)
endfunction()

set(positive_probes "")
set(negative_probes "")
foreach(m ${layer_modules})
  if(DEFINED LAYER_TARGET_${m})
    set(target ${LAYER_TARGET_${m}})
  else()
    set(target tracer_${m})
  endif()
  set(sees ${m})
  foreach(d ${LAYER_PUBLIC_${m}} ${LAYER_PRIVATE_${m}})
    if(d STREQUAL "cuda" AND NOT TRACER_HAS_CUDA)
      continue()
    endif()
    layer_exports(${d} e)
    list(APPEND sees ${e})
  endforeach()
  # The include path of the module's own sources (transitive over what it links).
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "INTERFACE_LIBRARY")
    set(includes "$<TARGET_PROPERTY:${target},INTERFACE_INCLUDE_DIRECTORIES>")
  else()
    set(includes "$<TARGET_PROPERTY:${target},INCLUDE_DIRECTORIES>")
  endif()
  set(allowed "")
  foreach(x ${layer_modules})
    if(NOT LAYER_HEADER_${x})
      continue()
    endif()
    list(FIND sees ${x} seen)
    if(seen GREATER -1)
      string(APPEND allowed "#include \"${LAYER_HEADER_${x}}\"\n")
    else()
      set(probe layer_probe_${m}_includes_${x})
      file(CONFIGURE OUTPUT ${CMAKE_CURRENT_BINARY_DIR}/layers/${probe}.cpp
           CONTENT "#include \"${LAYER_HEADER_${x}}\"\n")
      add_library(${probe} OBJECT EXCLUDE_FROM_ALL layers/${probe}.cpp)
      target_include_directories(${probe} PRIVATE ${includes})
      list(APPEND negative_probes "${probe}|${LAYER_HEADER_${x}}")
    endif()
  endforeach()
  set(probe layer_probe_${m}_allowed)
  file(CONFIGURE OUTPUT ${CMAKE_CURRENT_BINARY_DIR}/layers/${probe}.cpp CONTENT "${allowed}")
  add_library(${probe} OBJECT EXCLUDE_FROM_ALL layers/${probe}.cpp)
  target_include_directories(${probe} PRIVATE ${includes})
  list(APPEND positive_probes ${probe})
endforeach()

add_test(NAME Layers.UpwardIncludesFailToBuild
         COMMAND ${CMAKE_COMMAND} -D BUILD_DIR=${PROJECT_BINARY_DIR}
                 -D "GENERATOR=${CMAKE_GENERATOR}" -D "POSITIVE=${positive_probes}"
                 -D "NEGATIVE=${negative_probes}" -P ${CMAKE_CURRENT_SOURCE_DIR}/check_layers.cmake)
set_tests_properties(Layers.UpwardIncludesFailToBuild PROPERTIES LABELS cpu RESOURCE_LOCK build_tree)
