# lagcodegenCheckOutputs.cmake -- run by lagcodegen_generate() after `lagcodegen generate`:
# the stamp lists the files written; if they are not those CMake was configured with (a model
# renamed without PREFIX, an option changed by hand), stop and ask for a new configure.
#   cmake -DSTAMP=<stamp> -DEXPECTED=<outputs> -DTARGET=<target> -P lagcodegenCheckOutputs.cmake
file(READ "${STAMP}" _written)
file(READ "${EXPECTED}" _expected)
string(STRIP "${_written}" _written)
string(STRIP "${_expected}" _expected)
if(NOT _written STREQUAL _expected)
  message(FATAL_ERROR "lagcodegen: the generated files of ${TARGET} changed; re-run CMake.\n"
                      "configured with:\n${_expected}\nnow:\n${_written}")
endif()
