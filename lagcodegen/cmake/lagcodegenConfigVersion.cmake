# lagcodegenConfigVersion.cmake -- the version of this lagcodegen, read from lagcodegen/version.py
# (one place for it). Compatible with a requested version of the same major number that is not
# newer (for 0.x: the same minor number).
file(STRINGS "${CMAKE_CURRENT_LIST_DIR}/../version.py" _lagcodegen_version_line REGEX "^__version__")
string(REGEX MATCH "[0-9]+(\\.[0-9]+)*" PACKAGE_VERSION "${_lagcodegen_version_line}")
unset(_lagcodegen_version_line)

if(PACKAGE_FIND_VERSION AND PACKAGE_VERSION VERSION_LESS PACKAGE_FIND_VERSION)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
else()
  string(REPLACE "." ";" _lagcodegen_have "${PACKAGE_VERSION}")
  string(REPLACE "." ";" _lagcodegen_want "${PACKAGE_FIND_VERSION}.0")
  list(GET _lagcodegen_have 0 _lagcodegen_have_major)
  list(GET _lagcodegen_want 0 _lagcodegen_want_major)
  set(PACKAGE_VERSION_COMPATIBLE TRUE)
  if(PACKAGE_FIND_VERSION AND NOT _lagcodegen_have_major EQUAL _lagcodegen_want_major)
    set(PACKAGE_VERSION_COMPATIBLE FALSE)
  elseif(PACKAGE_FIND_VERSION AND _lagcodegen_have_major EQUAL 0)
    list(GET _lagcodegen_have 1 _lagcodegen_have_minor)
    list(GET _lagcodegen_want 1 _lagcodegen_want_minor)
    if(NOT _lagcodegen_have_minor EQUAL _lagcodegen_want_minor)
      set(PACKAGE_VERSION_COMPATIBLE FALSE)
    endif()
  endif()
  if(PACKAGE_FIND_VERSION AND PACKAGE_VERSION VERSION_EQUAL PACKAGE_FIND_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
  endif()
endif()
# Generated code is plain C99/Fortran 2008 source: any architecture (no pointer-size check).
