# lidartag_version: an interface target whose include path holds lidartag/version.hpp, generated
# on every build (cmake/WriteVersion.cmake) so that `--version` names the commit that was built.
set(LIDARTAG_VERSION_HEADER ${PROJECT_BINARY_DIR}/generated/lidartag/version.hpp)
add_custom_target(lidartag_version_header
  COMMAND ${CMAKE_COMMAND} -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
          -DTEMPLATE=${PROJECT_SOURCE_DIR}/cmake/version.hpp.in -DOUTPUT=${LIDARTAG_VERSION_HEADER}
          -DLIDARTAG_VERSION=${PROJECT_VERSION} -P ${PROJECT_SOURCE_DIR}/cmake/WriteVersion.cmake
  BYPRODUCTS ${LIDARTAG_VERSION_HEADER}
  COMMENT "" VERBATIM)
add_library(lidartag_version INTERFACE)
target_include_directories(lidartag_version INTERFACE ${PROJECT_BINARY_DIR}/generated)
add_dependencies(lidartag_version lidartag_version_header)
