# Finds ONNX Runtime (C/C++ API) and defines the imported target onnxruntime::onnxruntime.
#
# Search order:
#   1. ONNXRUNTIME_ROOT (CMake variable or environment variable): an unpacked official release
#      archive or any prefix with include/ and lib/; only there when it is set.
#   2. <source>/.deps/onnxruntime, where scripts/install_onnxruntime.sh puts its local copy.
#   3. The system: an ONNX Runtime CMake package (find_package(onnxruntime CONFIG)), pkg-config's
#      libonnxruntime, then the default include and library paths.
#
# Sets OnnxRuntime_FOUND, OnnxRuntime_INCLUDE_DIR, OnnxRuntime_LIBRARY (unless a CMake package was
# used) and OnnxRuntime_VERSION (from ORT_API_VERSION: 1.<api>.x). The target is GLOBAL so every
# directory can link it; executables get the library's folder in their build RPATH (CMake's
# default for linked shared libraries), so they run without LD_LIBRARY_PATH.

if(TARGET onnxruntime::onnxruntime)
  set(OnnxRuntime_FOUND TRUE)
  return()
endif()

set(_ort_root "")
if(ONNXRUNTIME_ROOT)
  set(_ort_root "${ONNXRUNTIME_ROOT}")
elseif(DEFINED ENV{ONNXRUNTIME_ROOT} AND NOT "$ENV{ONNXRUNTIME_ROOT}" STREQUAL "")
  set(_ort_root "$ENV{ONNXRUNTIME_ROOT}")
endif()
set(_ort_local "${PROJECT_SOURCE_DIR}/.deps/onnxruntime")
set(_ort_suffixes include include/onnxruntime include/onnxruntime/core/session)

function(_ort_search_prefix prefix)
  find_path(OnnxRuntime_INCLUDE_DIR onnxruntime_cxx_api.h PATHS "${prefix}"
            PATH_SUFFIXES ${_ort_suffixes} NO_DEFAULT_PATH)
  find_library(OnnxRuntime_LIBRARY NAMES onnxruntime PATHS "${prefix}"
               PATH_SUFFIXES lib lib64 lib/${CMAKE_LIBRARY_ARCHITECTURE} NO_DEFAULT_PATH)
endfunction()

set(_ort_source "")
if(_ort_root)
  _ort_search_prefix("${_ort_root}")
  set(_ort_source "ONNXRUNTIME_ROOT=${_ort_root}")
elseif(EXISTS "${_ort_local}/INSTALLED")
  _ort_search_prefix("${_ort_local}")
  set(_ort_source "${_ort_local} (scripts/install_onnxruntime.sh)")
endif()

if(NOT _ort_root AND NOT (OnnxRuntime_INCLUDE_DIR AND OnnxRuntime_LIBRARY))
  # A system install: its own CMake package first.
  find_package(onnxruntime CONFIG QUIET)
  if(TARGET onnxruntime::onnxruntime)
    get_target_property(_ort_imported onnxruntime::onnxruntime IMPORTED)
    if(_ort_imported)
      set_target_properties(onnxruntime::onnxruntime PROPERTIES IMPORTED_GLOBAL TRUE)
    endif()
    set(OnnxRuntime_FOUND TRUE)
    set(OnnxRuntime_VERSION "${onnxruntime_VERSION}")
    message(STATUS "Found ONNX Runtime ${onnxruntime_VERSION} (CMake package in ${onnxruntime_DIR})")
    return()
  endif()
  find_package(PkgConfig QUIET)
  if(PKG_CONFIG_FOUND)
    pkg_check_modules(_ort_pc QUIET libonnxruntime)
  endif()
  find_path(OnnxRuntime_INCLUDE_DIR onnxruntime_cxx_api.h HINTS ${_ort_pc_INCLUDE_DIRS}
            PATH_SUFFIXES onnxruntime onnxruntime/core/session)
  find_library(OnnxRuntime_LIBRARY NAMES onnxruntime HINTS ${_ort_pc_LIBRARY_DIRS})
  set(_ort_source "system")
endif()

if(OnnxRuntime_INCLUDE_DIR AND EXISTS "${OnnxRuntime_INCLUDE_DIR}/onnxruntime_c_api.h")
  file(STRINGS "${OnnxRuntime_INCLUDE_DIR}/onnxruntime_c_api.h" _ort_api_line
       REGEX "^#define ORT_API_VERSION [0-9]+")
  string(REGEX REPLACE "^#define ORT_API_VERSION ([0-9]+).*" "\\1" _ort_api "${_ort_api_line}")
  if(_ort_api)
    set(OnnxRuntime_VERSION "1.${_ort_api}")
  endif()
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(
  OnnxRuntime
  REQUIRED_VARS OnnxRuntime_LIBRARY OnnxRuntime_INCLUDE_DIR
  VERSION_VAR OnnxRuntime_VERSION
  REASON_FAILURE_MESSAGE
    "run scripts/install_onnxruntime.sh (local copy in .deps/onnxruntime), or install ONNX Runtime \
(a distribution package, or an official release archive) and set ONNXRUNTIME_ROOT to its folder")

if(OnnxRuntime_FOUND)
  message(STATUS "ONNX Runtime from ${_ort_source}: ${OnnxRuntime_LIBRARY}")
  add_library(onnxruntime::onnxruntime SHARED IMPORTED GLOBAL)
  set_target_properties(
    onnxruntime::onnxruntime PROPERTIES IMPORTED_LOCATION "${OnnxRuntime_LIBRARY}"
                                        INTERFACE_INCLUDE_DIRECTORIES "${OnnxRuntime_INCLUDE_DIR}")
endif()
mark_as_advanced(OnnxRuntime_INCLUDE_DIR OnnxRuntime_LIBRARY)
