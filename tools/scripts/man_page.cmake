# Script mode (cmake -P): one man page by help2man from a program's --help and --version.
# A subcommand (SUB) gets its own page (lidartag-detect.1) through a wrapper script named after
# the page, so that help2man titles it LIDARTAG-DETECT.
# Inputs: HELP2MAN, PROGRAM, SUB (optional), PAGE, OUTPUT, INCLUDE (an .h2m file), SEE_ALSO
# (pages, comma-separated), WORK_DIR.
file(MAKE_DIRECTORY ${WORK_DIR})
get_filename_component(out_dir ${OUTPUT} DIRECTORY)
file(MAKE_DIRECTORY ${out_dir})
set(exe ${PROGRAM})
if(SUB)
  set(exe ${WORK_DIR}/${PAGE})
  # help2man takes the page's name from the first word of --version.
  file(WRITE ${exe} "#!/bin/sh\nif [ \"$1\" = --version ]; then\n"
                    "  '${PROGRAM}' --version | sed '1s/^[^ ]*/${PAGE}/'\n  exit\nfi\n"
                    "exec '${PROGRAM}' ${SUB} \"$@\"\n")
  file(CHMOD ${exe} PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE
                                WORLD_READ WORLD_EXECUTE)
endif()
execute_process(COMMAND ${exe} --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${exe} --help failed")
endif()
# The NAME line: the help's first line without "program: ", up to its first sentence's end.
string(REGEX MATCH "^[^\n]*" name "${help}")
string(REGEX REPLACE "^[a-z-]+: " "" name "${name}")
string(REGEX REPLACE "\\. .*$" "" name "${name}")
# SEE ALSO: every other page of the project.
string(REPLACE "," ";" pages "${SEE_ALSO}")
list(REMOVE_ITEM pages ${PAGE})
set(see_also "[SEE ALSO]\n")
set(first TRUE)
foreach(p ${pages})
  if(NOT first)
    string(APPEND see_also ",\n")
  endif()
  string(APPEND see_also ".BR ${p} (1)")
  set(first FALSE)
endforeach()
string(APPEND see_also "\n.PP\nThe project's README.md and docs/ describe every command in detail.\n")
file(WRITE ${WORK_DIR}/${PAGE}.see-also.h2m "${see_also}")
execute_process(
  COMMAND ${HELP2MAN} --no-info --name=${name} --include=${INCLUDE}
          --include=${WORK_DIR}/${PAGE}.see-also.h2m --output=${OUTPUT} ${exe}
  RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "help2man ${PAGE}: ${err}")
endif()
