# Writes the man pages of the command line from its --help: OUTPUT_DIR/chronomap.1.gz and
# chronomap-COMMAND.1.gz for every subcommand its --help lists, by help2man (gzip -n: the same
# bytes from the same help text).
# Run as a script: cmake -DCLI=... -DHELP2MAN=... -DGZIP=... -DOUTPUT_DIR=... -P MakeManPages.cmake
execute_process(COMMAND "${CLI}" --help OUTPUT_VARIABLE help RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "${CLI} --help failed (${result})")
endif()
string(REGEX REPLACE ".*\nSubcommands:\n" "" listed "${help}")
# As a CMake list of lines: no semicolons, and no brackets (they keep a list from splitting).
string(REPLACE ";" "," listed "${listed}")
string(REPLACE "[" "(" listed "${listed}")
string(REPLACE "]" ")" listed "${listed}")
string(REPLACE "\n" ";" lines "${listed}")
file(REMOVE_RECURSE "${OUTPUT_DIR}")
file(MAKE_DIRECTORY "${OUTPUT_DIR}")

# help2man names the page after the program: a command's page is renamed (title and NAME).
function(make_page page help_option description)
  set(file ${OUTPUT_DIR}/${page}.1)
  execute_process(COMMAND "${HELP2MAN}" --no-info "--help-option=${help_option}" "--name=${description}"
                          --section=1 --output=${file} "${CLI}"
                  RESULT_VARIABLE result ERROR_VARIABLE error)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "help2man failed for ${page}: ${error}")
  endif()
  if(NOT page STREQUAL "chronomap")
    file(READ ${file} text)
    string(TOUPPER "${page}" title)
    string(REPLACE ".TH CHRONOMAP " ".TH ${title} " text "${text}")
    string(REPLACE "\n.SH NAME\nchronomap \\- " "\n.SH NAME\n${page} \\- " text "${text}")
    file(WRITE ${file} "${text}")
  endif()
  execute_process(COMMAND "${GZIP}" -n -9 -f ${file} RESULT_VARIABLE result)
  if(NOT result EQUAL 0)
    message(FATAL_ERROR "gzip failed for ${file}")
  endif()
endfunction()

make_page(chronomap --help "four-dimensional maps from RGB-D recordings of one place")
# Each command's line in the list: two spaces, its name, its description (first sentence taken).
foreach(line ${lines})
  if(line MATCHES "^  ([a-z][a-z0-9-]*) +(.*)$")
    set(name ${CMAKE_MATCH_1})
    string(REGEX REPLACE "\\. .*" "" description "${CMAKE_MATCH_2}")
    string(REGEX REPLACE "\\.$" "" description "${description}")
    make_page(chronomap-${name} "${name} --help" "${description}")
  endif()
endforeach()
