# FindCHOLMOD: CHOLMOD from SuiteSparse 5.x (Debian 12: libsuitesparse-dev 1:5.12), which
# ships neither a CMake package configuration nor a pkg-config file.
#
# Result: the imported target CHOLMOD::CHOLMOD (headers in <prefix>/include/suitesparse,
# libcholmod plus the ordering libraries it is built with), CHOLMOD_FOUND, CHOLMOD_VERSION.
# Hints: CHOLMOD_ROOT (CMake's <Package>_ROOT), or CHOLMOD_INCLUDE_DIR / CHOLMOD_LIBRARY.
#
# Licence: the Supernodal module of libcholmod is GPL-2+ (Core and Cholesky are LGPL-2.1+),
# so a binary that links this target is GPL-bound.
# BLAS/LAPACK: libcholmod.so already records its BLAS and LAPACK (Debian's alternatives
# pick the implementation at run time), so nothing is added here.

find_path(CHOLMOD_INCLUDE_DIR NAMES cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY NAMES cholmod)
foreach(_lib suitesparseconfig amd camd colamd ccolamd)
  string(TOUPPER ${_lib} _LIB)
  find_library(CHOLMOD_${_LIB}_LIBRARY NAMES ${_lib})
  mark_as_advanced(CHOLMOD_${_LIB}_LIBRARY)
endforeach()

if(CHOLMOD_INCLUDE_DIR AND EXISTS "${CHOLMOD_INCLUDE_DIR}/cholmod_core.h")
  file(STRINGS "${CHOLMOD_INCLUDE_DIR}/cholmod_core.h" _cholmod_version_lines
       REGEX "^#define CHOLMOD_(MAIN|SUB|SUBSUB)_VERSION[ \t]+[0-9]+")
  foreach(_part MAIN SUB SUBSUB)
    string(REGEX REPLACE ".*#define CHOLMOD_${_part}_VERSION[ \t]+([0-9]+).*" "\\1" _cholmod_${_part}
           "${_cholmod_version_lines}")
  endforeach()
  set(CHOLMOD_VERSION "${_cholmod_MAIN}.${_cholmod_SUB}.${_cholmod_SUBSUB}")
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD
  REQUIRED_VARS CHOLMOD_LIBRARY CHOLMOD_INCLUDE_DIR CHOLMOD_SUITESPARSECONFIG_LIBRARY CHOLMOD_AMD_LIBRARY
                CHOLMOD_CAMD_LIBRARY CHOLMOD_COLAMD_LIBRARY CHOLMOD_CCOLAMD_LIBRARY
  VERSION_VAR CHOLMOD_VERSION)
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY)

if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${CHOLMOD_AMD_LIBRARY};${CHOLMOD_CAMD_LIBRARY};${CHOLMOD_COLAMD_LIBRARY};${CHOLMOD_CCOLAMD_LIBRARY};${CHOLMOD_SUITESPARSECONFIG_LIBRARY}")
endif()
