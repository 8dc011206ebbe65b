# The firmware's version, from git when the source is a checkout: the project's version, then
# "+git.<commits>.<hash>" and ".dirty" for uncommitted changes (a Debian version's upstream
# part). Without git (a source tarball) the project's version alone.
#   calbox_version(SOURCE_DIR PROJECT_VERSION OUT_VAR)      at configure time (the .deb's)
#   cmake -DSOURCE_DIR=.. -DPROJECT_VERSION=.. -DOUT=file.cpp -P version.cmake
#                                                           at build time: the binary's, the file
#                                                           rewritten only when it changes
function(calbox_version source_dir project_version out_var)
  set(version "${project_version}")
  find_program(CALBOX_GIT git)
  if(CALBOX_GIT AND EXISTS "${source_dir}/.git")
    execute_process(COMMAND "${CALBOX_GIT}" -C "${source_dir}" rev-list --count HEAD
                    OUTPUT_VARIABLE count OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE r1
                    ERROR_QUIET)
    execute_process(COMMAND "${CALBOX_GIT}" -C "${source_dir}" describe --always --dirty=.dirty
                            --abbrev=7 --match "calbox-no-tag-matches-this"
                    OUTPUT_VARIABLE hash OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE r2
                    ERROR_QUIET)
    if(r1 EQUAL 0 AND r2 EQUAL 0 AND NOT count STREQUAL "" AND NOT hash STREQUAL "")
      set(version "${project_version}+git.${count}.${hash}")
    endif()
  endif()
  set(${out_var} "${version}" PARENT_SCOPE)
endfunction()

if(CMAKE_SCRIPT_MODE_FILE AND OUT)
  calbox_version("${SOURCE_DIR}" "${PROJECT_VERSION}" version)
  set(text "// Generated at build time by cmake/version.cmake.\n#include \"firmware/cli/version.hpp\"\n\nconst char* calbox::build_version() {\n    return \"${version}\";\n}\n")
  if(EXISTS "${OUT}")
    file(READ "${OUT}" old)
  endif()
  if(NOT old STREQUAL text)
    file(WRITE "${OUT}" "${text}")
  endif()
endif()
