# lagcodegenConfig.cmake -- lagcodegen as a build step of a CMake project.
#
#   find_package(lagcodegen CONFIG REQUIRED)   # -Dlagcodegen_DIR="$(lagcodegen --cmake-dir)"
#   lagcodegen_generate(TARGET pendulum MODEL pendulum.toml)
#   target_link_libraries(my_program PRIVATE pendulum)
#
# Variables set: lagcodegen_FOUND, lagcodegen_VERSION, LAGCODEGEN_EXECUTABLE (cache: the
# `lagcodegen` command; by default the one next to this package's Python, else on PATH).
#
# lagcodegen_generate(TARGET <target> MODEL <file.toml | file.py:function>
#                     [PREFIX <prefix>] [LANG C|Fortran]
#                     [OUTPUTS <name>...] [RUNTIME_PARAMETERS [<name>...]] [SET <name>=<value>...]
#                     [NO_JACOBIAN] [FORMULATION index1|ggl|minimal] [METHOD bdf|adams]
#                     [LIBRARY STATIC|SHARED|OBJECT] [OUTPUT_DIR <dir>] [POSITION_INDEPENDENT_CODE])
#
#   A library target <target> (type LIBRARY, else by BUILD_SHARED_LIBS) with the generated
#   sources, their folder as PUBLIC include directory, libm, C99 (and, with LANG Fortran, the
#   Fortran module folder as include directory). The sources are written at build time into
#   OUTPUT_DIR (default ${CMAKE_CURRENT_BINARY_DIR}/lagcodegen/<target>) by
#   `lagcodegen generate`, which runs again when, and only when, the model file (for a Python
#   model: the file and the modules it imports from its folder), the options or lagcodegen
#   itself change (depfile + stamp; unchanged files are not rewritten, so with Ninja nothing
#   recompiles when the code is the same). RUNTIME_PARAMETERS given without names folds every
#   parameter. The file names are learnt at configure time (`generate --list-outputs`, which
#   reads the manifest without deriving when it matches); if they change (a renamed model
#   without PREFIX), the build stops and asks to re-run CMake.
#   A Python model (file.py:function) is executed by lagcodegen, at configure and build time.
#   Sets <target>_LAGCODEGEN_FILES (every generated file) in the caller's scope.

if(CMAKE_VERSION VERSION_LESS 3.20)
  set(lagcodegen_FOUND FALSE)
  set(lagcodegen_NOT_FOUND_MESSAGE "lagcodegen_generate needs CMake 3.20 or newer (DEPFILE with Makefiles)")
  return()
endif()

cmake_policy(PUSH)
cmake_policy(VERSION 3.20...3.29)

include("${CMAKE_CURRENT_LIST_DIR}/lagcodegenConfigVersion.cmake")
set(lagcodegen_VERSION "${PACKAGE_VERSION}")
get_filename_component(_lagcodegen_package_dir "${CMAKE_CURRENT_LIST_DIR}/.." ABSOLUTE)

if(NOT LAGCODEGEN_EXECUTABLE)
  # A wheel installs this folder as <prefix>/lib/pythonX.Y/site-packages/lagcodegen/cmake and
  # the command as <prefix>/bin/lagcodegen (Windows: <prefix>/Lib/site-packages, <prefix>/Scripts).
  find_program(LAGCODEGEN_EXECUTABLE NAMES lagcodegen
               HINTS "${_lagcodegen_package_dir}/../../../../bin" "${_lagcodegen_package_dir}/../../../Scripts"
               DOC "the lagcodegen command")
endif()
if(NOT LAGCODEGEN_EXECUTABLE)
  set(lagcodegen_FOUND FALSE)
  set(lagcodegen_NOT_FOUND_MESSAGE "the `lagcodegen` command was not found: put it on PATH or set LAGCODEGEN_EXECUTABLE")
  cmake_policy(POP)
  return()
endif()
execute_process(COMMAND "${LAGCODEGEN_EXECUTABLE}" --cmake-dir OUTPUT_VARIABLE _lagcodegen_dir
                RESULT_VARIABLE _lagcodegen_rc OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT _lagcodegen_rc EQUAL 0)
  set(lagcodegen_FOUND FALSE)
  set(lagcodegen_NOT_FOUND_MESSAGE "${LAGCODEGEN_EXECUTABLE} --cmake-dir failed (exit ${_lagcodegen_rc})")
  cmake_policy(POP)
  return()
endif()
get_filename_component(_lagcodegen_dir "${_lagcodegen_dir}" REALPATH)
get_filename_component(_lagcodegen_here "${CMAKE_CURRENT_LIST_DIR}" REALPATH)
if(NOT _lagcodegen_dir STREQUAL _lagcodegen_here)
  message(WARNING "lagcodegen: ${LAGCODEGEN_EXECUTABLE} belongs to ${_lagcodegen_dir}, not to this package "
                  "(${_lagcodegen_here}); set LAGCODEGEN_EXECUTABLE to the command of the same installation")
endif()
set(lagcodegen_FOUND TRUE)

set(_lagcodegen_check_script "${CMAKE_CURRENT_LIST_DIR}/lagcodegenCheckOutputs.cmake")
find_library(LAGCODEGEN_LIBM m)
mark_as_advanced(LAGCODEGEN_LIBM)

function(lagcodegen_generate)
  cmake_parse_arguments(PARSE_ARGV 0 arg "NO_JACOBIAN;POSITION_INDEPENDENT_CODE"
                        "TARGET;MODEL;PREFIX;LANG;FORMULATION;METHOD;LIBRARY;OUTPUT_DIR"
                        "OUTPUTS;RUNTIME_PARAMETERS;SET")
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "lagcodegen_generate: unknown arguments ${arg_UNPARSED_ARGUMENTS}")
  endif()
  foreach(required TARGET MODEL)
    if(NOT arg_${required})
      message(FATAL_ERROR "lagcodegen_generate: ${required} is required")
    endif()
  endforeach()

  # MODEL: file.toml or file.py:function, relative to the current source folder
  set(model "${arg_MODEL}")
  set(function "")
  if(model MATCHES "^(.+\\.py):([A-Za-z_][A-Za-z0-9_]*)$")
    set(model "${CMAKE_MATCH_1}")
    set(function ":${CMAKE_MATCH_2}")
  endif()
  get_filename_component(model "${model}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  if(NOT EXISTS "${model}")
    message(FATAL_ERROR "lagcodegen_generate(${arg_TARGET}): model file ${model} not found")
  endif()

  set(lang c)
  if(arg_LANG)
    string(TOLOWER "${arg_LANG}" lang)
    if(NOT lang MATCHES "^(c|fortran)$")
      message(FATAL_ERROR "lagcodegen_generate(${arg_TARGET}): LANG must be C or Fortran, not ${arg_LANG}")
    endif()
  endif()
  get_property(languages GLOBAL PROPERTY ENABLED_LANGUAGES)
  if(lang STREQUAL "fortran" AND NOT "Fortran" IN_LIST languages)
    message(FATAL_ERROR "lagcodegen_generate(${arg_TARGET}): LANG Fortran needs the Fortran language "
                        "(project(... LANGUAGES C Fortran) or enable_language(Fortran))")
  endif()

  if(arg_OUTPUT_DIR)
    get_filename_component(outdir "${arg_OUTPUT_DIR}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_BINARY_DIR}")
  else()
    set(outdir "${CMAKE_CURRENT_BINARY_DIR}/lagcodegen/${arg_TARGET}")
  endif()
  set(work "${CMAKE_CURRENT_BINARY_DIR}/CMakeFiles/lagcodegen")
  set(stamp "${work}/${arg_TARGET}.stamp")
  set(depfile "${work}/${arg_TARGET}.d")
  set(optfile "${work}/${arg_TARGET}.options")

  set(args generate "${model}${function}" -o "${outdir}" --lang ${lang} -q)
  if(arg_PREFIX)
    list(APPEND args --prefix "${arg_PREFIX}")
  endif()
  if(arg_OUTPUTS)
    list(JOIN arg_OUTPUTS "," joined)
    list(APPEND args --outputs "${joined}")
  endif()
  if(arg_RUNTIME_PARAMETERS)
    list(JOIN arg_RUNTIME_PARAMETERS "," joined)
    list(APPEND args --runtime-parameters "${joined}")
  elseif("RUNTIME_PARAMETERS" IN_LIST arg_KEYWORDS_MISSING_VALUES)
    list(APPEND args --fold-all)
  endif()
  foreach(assignment IN LISTS arg_SET)
    list(APPEND args --set "${assignment}")
  endforeach()
  if(arg_NO_JACOBIAN)
    list(APPEND args --no-jacobian)
  endif()
  if(arg_FORMULATION)
    list(APPEND args --formulation "${arg_FORMULATION}")
  endif()
  if(arg_METHOD)
    string(TOLOWER "${arg_METHOD}" method)
    list(APPEND args --method "${method}")
  endif()

  # The file names, at configure time (from the manifest when it matches: no derivation).
  execute_process(COMMAND "${LAGCODEGEN_EXECUTABLE}" ${args} --list-outputs
                  RESULT_VARIABLE rc OUTPUT_VARIABLE listed ERROR_VARIABLE errors)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "lagcodegen_generate(${arg_TARGET}): lagcodegen generate --list-outputs failed "
                        "(exit ${rc}):\n${errors}")
  endif()
  string(STRIP "${listed}" listed)
  string(REPLACE "\n" ";" files "${listed}")
  set(sources "")
  set(headers "")
  foreach(file IN LISTS files)
    if(file MATCHES "\\.(c|f90)$")
      list(APPEND sources "${file}")
    elseif(file MATCHES "\\.h$")
      list(APPEND headers "${file}")
    endif()
  endforeach()
  if(NOT sources)
    message(FATAL_ERROR "lagcodegen_generate(${arg_TARGET}): lagcodegen lists no source file:\n${listed}")
  endif()

  # The command line is a dependency too (Makefiles do not rerun a rule whose command changed):
  # this file is rewritten only when it changes.
  string(REPLACE ";" "\n" options_text "${LAGCODEGEN_EXECUTABLE};${args};${files}")
  file(CONFIGURE OUTPUT "${optfile}" CONTENT "${options_text}\n" @ONLY)

  string(REPLACE ";" "\n" expected "${files}")
  file(CONFIGURE OUTPUT "${work}/${arg_TARGET}.outputs" CONTENT "${expected}\n" @ONLY)
  add_custom_command(
    OUTPUT "${stamp}"
    BYPRODUCTS ${files}
    COMMAND "${LAGCODEGEN_EXECUTABLE}" ${args} --stamp "${stamp}" --depfile "${depfile}"
    COMMAND "${CMAKE_COMMAND}" -DSTAMP=${stamp} -DEXPECTED=${work}/${arg_TARGET}.outputs
            -DTARGET=${arg_TARGET} -P "${_lagcodegen_check_script}"
    DEPENDS "${model}" "${LAGCODEGEN_EXECUTABLE}" "${optfile}"
    DEPFILE "${depfile}"
    COMMENT "lagcodegen: generating ${arg_TARGET} from ${arg_MODEL}"
    VERBATIM)

  add_library(${arg_TARGET} ${arg_LIBRARY} ${sources} ${headers} "${stamp}")
  target_include_directories(${arg_TARGET} PUBLIC "$<BUILD_INTERFACE:${outdir}>")
  set_target_properties(${arg_TARGET} PROPERTIES C_STANDARD 99 C_STANDARD_REQUIRED ON
                        LAGCODEGEN_OUTPUT_DIR "${outdir}")
  if(lang STREQUAL "fortran")
    set_target_properties(${arg_TARGET} PROPERTIES Fortran_MODULE_DIRECTORY "${outdir}/modules")
    target_include_directories(${arg_TARGET} PUBLIC "$<BUILD_INTERFACE:${outdir}/modules>")
  endif()
  if(arg_POSITION_INDEPENDENT_CODE)
    set_target_properties(${arg_TARGET} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  endif()
  if(LAGCODEGEN_LIBM)
    target_link_libraries(${arg_TARGET} PUBLIC m)
  endif()
  set(${arg_TARGET}_LAGCODEGEN_FILES ${files} PARENT_SCOPE)
endfunction()

define_property(TARGET PROPERTY LAGCODEGEN_OUTPUT_DIR BRIEF_DOCS "lagcodegen output folder"
                FULL_DOCS "The folder lagcodegen_generate() writes the target's sources into.")

cmake_policy(POP)
