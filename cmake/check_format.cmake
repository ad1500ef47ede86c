# Fails when any C++ file of the project differs from clang-format's output (.clang-format).
# Usage: cmake -DCLANG_FORMAT=/usr/bin/clang-format -DSOURCE_DIR=<repo> -P check_format.cmake
file(GLOB_RECURSE files
     ${SOURCE_DIR}/include/*.h ${SOURCE_DIR}/src/*.h ${SOURCE_DIR}/src/*.cc
     ${SOURCE_DIR}/apps/*.h ${SOURCE_DIR}/apps/*.cc ${SOURCE_DIR}/tests/*.h
     ${SOURCE_DIR}/tests/*.cc ${SOURCE_DIR}/bench/*.h ${SOURCE_DIR}/bench/*.cc
     ${SOURCE_DIR}/fuzz/*.h ${SOURCE_DIR}/fuzz/*.cc)
execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${files} RESULT_VARIABLE result
                ERROR_VARIABLE diagnostics)
list(LENGTH files count)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "clang-format: files need formatting (run clang-format -i):\n${diagnostics}")
endif()
message(STATUS "clang-format: ${count} files formatted")
