# `cmake --install build/release --prefix PREFIX` installs
#   PREFIX/bin/weft                         the command line
#   PREFIX/lib/libweft_*.a                  one library per layer
#   PREFIX/include/weft/<layer>/*.hpp       the headers, included as "framework/simulator.hpp"
#   PREFIX/share/weft/{scripts,scenes}      what weft calls (plots, renders) and its shipped scenes
#   PREFIX/lib/cmake/weft/                  find_package(weft): weft::weft (every layer) and
#                                           weft::framework, weft::models, weft::integrators,
#                                           weft::contact, weft::linear, weft::policies
# The weft binary finds share/weft next to its own bin/ (apps/bench_common.cpp, data_dir()); the
# build tree mirrors that layout with links to the source's scripts/ and scenes/.
include(CMakePackageConfigHelpers)

set(weft_layers framework models integrators contact linear policies)
foreach(layer IN LISTS weft_layers)
  set_target_properties(weft_${layer} PROPERTIES EXPORT_NAME ${layer})
endforeach()
set_target_properties(weft_options PROPERTIES EXPORT_NAME options)
set(weft_backend_targets)
if(TARGET weft_cholmod)
  set_target_properties(weft_cholmod PROPERTIES EXPORT_NAME cholmod)
  list(APPEND weft_backend_targets weft_cholmod)
endif()
if(TARGET weft_petsc_gamg)
  set_target_properties(weft_petsc_gamg PROPERTIES EXPORT_NAME petsc_gamg)
  list(APPEND weft_backend_targets weft_petsc_gamg)
endif()
if(TARGET weft_policies_backends)  # the back ends' pre-built combinations (policies/CMakeLists.txt)
  set_target_properties(weft_policies_backends PROPERTIES EXPORT_NAME policies_backends)
  list(APPEND weft_backend_targets weft_policies_backends)
endif()

# weft::weft: the whole library, as a user's project links it.
add_library(weft_all INTERFACE)
set_target_properties(weft_all PROPERTIES EXPORT_NAME weft)
target_link_libraries(weft_all INTERFACE weft_policies ${weft_backend_targets})
add_library(weft::weft ALIAS weft_all)
foreach(layer IN LISTS weft_layers)
  add_library(weft::${layer} ALIAS weft_${layer})
endforeach()

install(TARGETS weft_options weft_framework weft_models weft_integrators weft_contact weft_linear
                weft_policies ${weft_backend_targets} weft_all
        EXPORT weftTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/weft)
install(TARGETS weft RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

foreach(layer IN LISTS weft_layers)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${layer}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/weft/${layer}
          FILES_MATCHING PATTERN "*.hpp")
endforeach()
install(PROGRAMS ${PROJECT_SOURCE_DIR}/scripts/weft_plot.py ${PROJECT_SOURCE_DIR}/scripts/weft_render.py
        DESTINATION ${CMAKE_INSTALL_DATADIR}/weft/scripts)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/scenes/ DESTINATION ${CMAKE_INSTALL_DATADIR}/weft/scenes)

set(weft_cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/weft)
install(EXPORT weftTargets NAMESPACE weft:: DESTINATION ${weft_cmake_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/weftConfig.cmake.in ${PROJECT_BINARY_DIR}/weftConfig.cmake
                              INSTALL_DESTINATION ${weft_cmake_dir} PATH_VARS CMAKE_INSTALL_DATADIR)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/weftConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/weftConfig.cmake ${PROJECT_BINARY_DIR}/weftConfigVersion.cmake
        DESTINATION ${weft_cmake_dir})
if(WEFT_WITH_CHOLMOD)
  install(FILES ${PROJECT_SOURCE_DIR}/cmake/FindCHOLMOD.cmake DESTINATION ${weft_cmake_dir})
endif()

# The build tree's share/weft: links to the source's scripts and scenes, so that the weft in
# build/<preset>/apps finds them as the installed one does.
file(MAKE_DIRECTORY ${PROJECT_BINARY_DIR}/share/weft)
foreach(d scripts scenes)
  if(NOT EXISTS ${PROJECT_BINARY_DIR}/share/weft/${d})
    file(CREATE_LINK ${PROJECT_SOURCE_DIR}/${d} ${PROJECT_BINARY_DIR}/share/weft/${d} SYMBOLIC)
  endif()
endforeach()

# A Debian package: cpack -G DEB in the build directory (weft_<version>_<arch>.deb).
set(CPACK_PACKAGE_NAME weft)
set(CPACK_PACKAGE_CONTACT "weft developers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_DEPENDS
    "libeigen3-dev, libboost-dev, libfmt-dev, nlohmann-json3-dev, libtinyobjloader-dev, liblapack-dev, libgomp1, python3")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "python3-matplotlib, povray, ffmpeg")
include(CPack)
