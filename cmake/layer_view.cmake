# Each library sees only the layers it may include, and the compiler enforces it: its one
# include directory is a folder of symbolic links in the build tree (the view) that holds those
# layers' folders and files under their own names, so that "core/..." reads as everywhere else
# and "drivers/..." from firmware/ is a missing file, not a review comment. tests/layers'
# test_layer_views compiles a forbidden include with each library's own flags and expects it
# refused. The tests, benchmarks and fuzz targets see the whole tree (their own directories).
#
# calbox_layer_view(TARGET PART...): PART is a folder or file relative to the source root
# (core, board/devices.hpp, core/net). The view's folder is named by a hash of its parts, so a
# changed list makes a new view rather than editing links a build may be reading.
function(calbox_layer_view target)
  string(SHA1 parts_hash "${ARGN}")
  string(SUBSTRING "${parts_hash}" 0 10 parts_hash)
  set(view "${CMAKE_BINARY_DIR}/layer_views/${target}-${parts_hash}")
  foreach(part IN LISTS ARGN)
    if(NOT EXISTS "${CMAKE_SOURCE_DIR}/${part}")
      message(FATAL_ERROR "calbox_layer_view(${target}): ${part} is not in the source tree")
    endif()
    if(EXISTS "${view}/${part}" AND NOT IS_SYMLINK "${view}/${part}")
      # Reached through another part's link: a link made here would land in the source tree.
      message(FATAL_ERROR "calbox_layer_view(${target}): ${part} is inside another of its parts")
    endif()
    if(NOT IS_SYMLINK "${view}/${part}")
      get_filename_component(parent "${view}/${part}" DIRECTORY)
      file(MAKE_DIRECTORY "${parent}")
      file(CREATE_LINK "${CMAKE_SOURCE_DIR}/${part}" "${view}/${part}" SYMBOLIC)
    endif()
  endforeach()
  target_include_directories(${target} PRIVATE "${view}")
endfunction()
