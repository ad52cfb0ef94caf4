# Script mode (cmake -P), run on every build: writes the version header from the project version
# and `git describe` of the source tree. configure_file leaves the header untouched when nothing
# changed, so nothing is recompiled. Without git, or when the source tree is not the top of a git
# checkout (a tarball unpacked inside another repository), the project version alone is used.
# Inputs: SOURCE_DIR, TEMPLATE, OUTPUT, LIDARTAG_VERSION.
set(LIDARTAG_GIT_DESCRIBE "")
find_program(GIT_EXECUTABLE git)
if(GIT_EXECUTABLE)
  execute_process(COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} rev-parse --show-toplevel
                  OUTPUT_VARIABLE top RESULT_VARIABLE top_rc ERROR_QUIET
                  OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(top_rc EQUAL 0)
    file(REAL_PATH "${top}" top)
    file(REAL_PATH "${SOURCE_DIR}" src)
    if(top STREQUAL src)
      execute_process(COMMAND ${GIT_EXECUTABLE} -C ${SOURCE_DIR} describe --tags --always --dirty
                      OUTPUT_VARIABLE describe RESULT_VARIABLE rc ERROR_QUIET
                      OUTPUT_STRIP_TRAILING_WHITESPACE)
      if(rc EQUAL 0)
        set(LIDARTAG_GIT_DESCRIBE "${describe}")
      endif()
    endif()
  endif()
endif()
if(LIDARTAG_GIT_DESCRIBE STREQUAL "")
  set(LIDARTAG_VERSION_STRING "${LIDARTAG_VERSION}")
else()
  set(LIDARTAG_VERSION_STRING "${LIDARTAG_VERSION} (git ${LIDARTAG_GIT_DESCRIBE})")
endif()
configure_file(${TEMPLATE} ${OUTPUT} @ONLY)
