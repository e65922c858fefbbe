# Runs a command and passes only when both its exit status and its output (stdout and stderr
# together) are what the test expects. ctest's PASS_REGULAR_EXPRESSION ignores the exit status, so
# a tool that printed the expected line and then failed, or printed a refusal and exited 0, would pass.
#   cmake -DSTATUS=<code> -DMATCH=<regex> -P tests/expect.cmake -- <command> [<argument>...]
# STATUS is the exact exit code (0, or the tool's code for that refusal: 1 for input it cannot read,
# 2 for a bad option). MATCH is a CMake regular expression, as PASS_REGULAR_EXPRESSION takes, and may
# hold ';'; the command's arguments may not (CMake would split them there).
# tests/CMakeLists.txt's mtlod_add_cli_test writes these command lines.
cmake_minimum_required(VERSION 3.25)

set(command "")
set(after_separator FALSE)
math(EXPR last "${CMAKE_ARGC} - 1")
foreach(i RANGE ${last})
  if(after_separator)
    list(APPEND command "${CMAKE_ARGV${i}}")
  elseif("${CMAKE_ARGV${i}}" STREQUAL "--")
    set(after_separator TRUE)
  endif()
endforeach()
if(command STREQUAL "" OR NOT DEFINED STATUS OR NOT DEFINED MATCH)
  message(FATAL_ERROR "usage: cmake -DSTATUS=<code> -DMATCH=<regex> -P expect.cmake -- <command> [<argument>...]")
endif()

execute_process(COMMAND ${command} RESULT_VARIABLE status OUTPUT_VARIABLE output ERROR_VARIABLE output)
# The command's own output first, so that ctest --output-on-failure shows what it printed.
message("${output}")
set(problems "")
if(NOT status STREQUAL STATUS)
  string(APPEND problems "\n  exit status ${status}, expected ${STATUS}")
endif()
if(NOT output MATCHES "${MATCH}")
  string(APPEND problems "\n  output does not match \"${MATCH}\"")
endif()
if(NOT problems STREQUAL "")
  string(JOIN " " shown ${command})
  message(FATAL_ERROR "${shown}:${problems}")
endif()
