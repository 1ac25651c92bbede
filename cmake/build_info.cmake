# Writes OUT (a C++ source defining weft::build_commit()) from `git describe --always --dirty`
# of SRC. Run at every build (target weft_build_info, framework/CMakeLists.txt); configure_file rewrites OUT
# only when the text changes, so an unchanged commit recompiles nothing.
execute_process(COMMAND git -C "${SRC}" describe --always --dirty --abbrev=12
                OUTPUT_VARIABLE WEFT_BUILD_COMMIT OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR WEFT_BUILD_COMMIT STREQUAL "")
  set(WEFT_BUILD_COMMIT "unknown (not built from a git checkout)")
endif()
configure_file("${IN}" "${OUT}" @ONLY)
